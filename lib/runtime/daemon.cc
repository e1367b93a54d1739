// zonemapd's session (see daemon.h).
#include "runtime/daemon.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <utility>

#include "runtime/summary.h"
#include "runtime/text_line.h"

namespace zm {
namespace {

// Writes all of `bytes` to a blocking fd. A signal interrupting a blocked write is retried: the
// line is finished, the stop takes effect at the next tick boundary.
bool WriteAll(int fd, std::string_view bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  return true;
}

bool IsPowerOfTwo(std::uint64_t n) { return n != 0 && (n & (n - 1)) == 0; }

// The camera frames a session reads (see daemon.h): a frames file's images, a recorded folder's,
// or the live input's by DaemonOptions::images. All zero: none.
Result<FrameSource::Images> SessionImages(const MapReader& map, const DaemonInput& input,
                                          const DaemonOptions& options, const FrameReader* replay) {
  const CameraIntrinsics& camera = map.metadata().camera;
  const auto sized = [&](std::uint32_t w, std::uint32_t h) -> Result<FrameSource::Images> {
    ZM_RETURN_IF_ERROR(CheckImageSize(camera, w, h));
    return FrameSource::Images{MaxEncodedImageBytes(w, h), w, h};
  };
  switch (input.kind) {
    case DaemonInput::Kind::kReplay: {
      const FramesFileInfo& i = replay->info();
      return FrameSource::Images{i.max_colour_bytes, i.image_width, i.image_height};
    }
    case DaemonInput::Kind::kCameraFiles:
      if (input.camera_files == nullptr) return InvalidArgument("no camera file source given");
      return sized(input.camera_files->width(), input.camera_files->height());
    case DaemonInput::Kind::kFd:
    case DaemonInput::Kind::kUdp:
      break;
  }
  bool on = options.images == DaemonImages::kOn;
  if (options.images == DaemonImages::kAuto) {
    // A map built from pixels has a vocabulary (import-tum, sim --features orb, import-rtabmap
    // --features orb): its keyframes hold the ORB features the front-end reproduces.
    ZM_ASSIGN_OR_RETURN(const auto blob, map.VocabularyBlob());
    on = blob.has_value();
  }
  if (!on) {
    if (options.image_width != 0 || options.image_height != 0) {
      return InvalidArgument(options.images == DaemonImages::kOff
                                 ? "an image size was given with images off"
                                 : "an image size was given, but the map has no vocabulary: "
                                   "give --images on to read image lines");
    }
    return FrameSource::Images{};
  }
  if ((options.image_width == 0) != (options.image_height == 0)) {
    return InvalidArgument("give both image width and height, or neither");
  }
  return options.image_width == 0 ? sized(camera.width, camera.height)
                                  : sized(options.image_width, options.image_height);
}

}  // namespace

Daemon::Daemon(const Profile& profile, const DaemonOptions& options, std::uint32_t max_features)
    : profile_(profile), options_(options), staged_(max_features) {}

Daemon::~Daemon() = default;

Result<std::unique_ptr<Daemon>> Daemon::Create(const Profile& profile, MapReader& map,
                                               const DaemonInput& input,
                                               const DaemonOptions& options) {
  if (options.max_features == 0) return InvalidArgument("--max-features must be at least 1");
  std::unique_ptr<FrameReader> replay;
  std::uint32_t max_features = options.max_features;
  if (input.kind == DaemonInput::Kind::kReplay) {
    ZM_ASSIGN_OR_RETURN(FrameReader reader, FrameReader::Open(input.frames_path));
    max_features = std::max(max_features, reader.max_features());
    replay = std::make_unique<FrameReader>(std::move(reader));
  }
  ZM_ASSIGN_OR_RETURN(const FrameSource::Images images,
                      SessionImages(map, input, options, replay.get()));
  std::unique_ptr<Daemon> d(new Daemon(profile, options, max_features));
  const std::uint32_t waypoints = profile.input.max_route_waypoints;
  const std::size_t line_bytes = MaxInputLineBytes(max_features, waypoints);
  switch (input.kind) {
    case DaemonInput::Kind::kFd:
      d->fd_reader_ = std::make_unique<FdLineReader>(input.fd, line_bytes);
      break;
    case DaemonInput::Kind::kUdp: {
      ZM_ASSIGN_OR_RETURN(d->udp_, UdpLineReader::Bind(input.udp_port, line_bytes));
      break;
    }
    case DaemonInput::Kind::kReplay:
      d->replay_ = std::move(replay);
      break;
    case DaemonInput::Kind::kCameraFiles:
      d->camera_files_ = input.camera_files;
      break;
  }
  d->input_.Reserve(max_features, waypoints);
  d->images_ = images;
  if (images.max_colour_bytes > 0) {
    // The loop's front-end writes up to its extractor's max_features into a frame, and the
    // session's, the staging and the loop's frame trade buffers by swapping: all three get the
    // same capacity (the loop reserves its own from the same two numbers).
    const std::uint32_t features = std::max(max_features, profile.orb.max_features);
    d->input_.frame.Reserve(features, images.max_colour_bytes);
    d->staged_.ExpectImages(images, features);
    d->image_reader_.Configure(images.width, images.height, images.max_colour_bytes);
  }
  d->staged_.set_probe(d.get());
  ZM_ASSIGN_OR_RETURN(d->loop_, TickLoop::Create(profile, map, d->staged_));
  d->loop_->ReserveRoute(waypoints);
  d->gate_ = std::make_unique<InputGate>(profile.input, ExtentOf(d->loop_->map_index()));
  d->out_.resize(std::max(kPoseLineMaxBytes, RouteAckMaxBytes(waypoints)));
  ZM_RETURN_IF_ERROR(d->publisher_.Open({.telemetry_path = options.telemetry_path,
                                         .estimate_path = options.estimate_path,
                                         .flush_ticks = profile.telemetry.flush_ticks,
                                         .track_status = true,
                                         .output = profile.output}));
  d->counters_.k_max_min = d->loop_->k_max();
  return d;
}

std::uint16_t Daemon::udp_port() const { return udp_ ? udp_->port() : 0; }

void Daemon::Hello() {
  const TickLoop& l = *loop_;
  const char* input = udp_                       ? "udp"
                      : replay_                  ? "frames"
                      : camera_files_ != nullptr ? camera_files_->kind()
                                                 : "stream";
  char images[32] = "off";
  if (images_.max_colour_bytes > 0)
    std::snprintf(images, sizeof images, "%ux%u", images_.width, images_.height);
  char buf[512];
  const int n = std::snprintf(
      buf, sizeof buf,
      "hello zonemapd %d policy %s k_max %u arena_slots %u slot_bytes %llu keyframes %u "
      "zones %zu max_features %u max_route_waypoints %u input %s images %s\n",
      kPoseProtocolVersion, PolicyName(l.config().policy.kind).data(), l.k_max(),
      l.arena().capacity(), static_cast<unsigned long long>(l.slot_bytes()),
      l.map_index().keyframe_count(), l.zone_set().size(), staged_.max_features(),
      profile_.input.max_route_waypoints, input, images);
  if (n > 0 && static_cast<std::size_t>(n) < sizeof buf) {
    if (options_.pose_fd >= 0 && !WriteAll(options_.pose_fd, {buf, static_cast<std::size_t>(n)})) {
      ++counters_.output_errors;
    }
  }
}

Result<bool> Daemon::Step() {
  if (!fatal_.ok()) return fatal_;
  if (ended_) return false;
  if (replay_) {
    ZM_ASSIGN_OR_RETURN(const bool more, replay_->Next(&input_.frame));
    if (!more) return false;
    ++counters_.lines;
    HandleFrame(1.0);  // a recorded pose is a rotation matrix already
  } else if (camera_files_ != nullptr) {
    CameraFrameFiles files;
    ZM_ASSIGN_OR_RETURN(const bool more, camera_files_->Next(&files));
    if (!more) return false;
    ++counters_.lines;
    input_.frame.stamp_s = files.stamp_s;
    input_.frame.odom = files.odom;
    HandleImage(1.0, files.colour_path, files.depth_path, files.note);  // a rotation already
  } else {
    std::string_view line;
    ZM_ASSIGN_OR_RETURN(const LineRead r,
                        fd_reader_ ? fd_reader_->NextLine(&line) : udp_->NextLine(&line));
    if (r == LineRead::kEnd) return false;
    ++counters_.lines;
    if (r == LineRead::kTooLong) {
      Refuse(RejectReason::kLineTooLong, "line longer than the longest valid line", 0);
    } else {
      Dispatch(line);
    }
  }
  if (!fatal_.ok()) return fatal_;
  return !ended_;
}

void Daemon::Dispatch(std::string_view line) {
  LineError err;
  switch (ParseInputLine(line, &input_, &err)) {
    case LineKind::kIgnored:
      return;
    case LineKind::kFrame:
      return HandleFrame(input_.quaternion_norm);
    case LineKind::kImage:
      if (images_.max_colour_bytes == 0) {
        return Refuse(RejectReason::kNoFrontEnd,
                      "an image line, but this zonemapd reads no images (--images off, or "
                      "--images auto on a map without a vocabulary: start it with --images on)",
                      0);
      }
      return HandleImage(input_.quaternion_norm, input_.colour_path, input_.depth_path, {});
    case LineKind::kRoute:
      return HandleRoute();
    case LineKind::kBudget:
      return HandleBudget(input_.budget_keyframes);
    case LineKind::kMalformed:
      Refuse(err.reason, err.what, err.column);
      // The robot waits for an answer to a control line: refusals are acknowledged too.
      if (err.reason == RejectReason::kRouteTooLong) {
        ++counters_.routes_rejected;
        Emit({out_.data(), FormatRouteAck(false, 0, {}, out_.data(), out_.size())});
      } else if (err.reason == RejectReason::kBudgetInvalid) {
        ++counters_.budget_changes;
        HandleBudget(0);
      }
      return;
  }
}

bool Daemon::Admit(double quaternion_norm) {
  RejectReason why = RejectReason::kSyntax;
  if (gate_->AcceptFrame(input_.frame, quaternion_norm, loop_->map_from_odom(), &why)) return true;
  Refuse(why, RejectRule(why), 0);
  return false;
}

// Hands input_.frame to the loop, ticks and publishes. false: nothing was processed (a fatal
// error, or --max-ticks reached: the staged frame is not processed).
bool Daemon::TickStaged() {
  std::swap(input_.frame, staged_.staging());  // both reserved: no allocation
  staged_.Stage();
  staged_.set_malformed_lines(rejects_.total);
  Result<bool> more = loop_->Tick();
  if (!more.ok()) {
    fatal_ = more.status();
    return false;
  }
  if (!more.value()) {
    ended_ = true;
    return false;
  }
  ++counters_.frames;
  AfterTick(loop_->last_record());
  return true;
}

void Daemon::HandleFrame(double quaternion_norm) {
  if (!Admit(quaternion_norm)) return;
  const double stamp = input_.frame.stamp_s;
  if (input_.frame.has_image()) ++counters_.image_frames;  // a frames file's camera frame
  if (!TickStaged()) return;
  // A recorded frame with an image the front-end could not use (a frames file's JPEG).
  if (loop_->last_record().image_refused) ReportFrontEndRefusal(stamp, "recorded frame");
  // The idle part, once the robot has its pose: queued zone loads advance until the next frame
  // is due or a line is already waiting (TickLoop::Idle; an error is counted by the loop).
  (void)loop_->Idle();
}

void Daemon::HandleImage(double quaternion_norm, std::string_view colour_path,
                         std::string_view depth_path, std::string_view note) {
  if (!Admit(quaternion_norm)) return;
  Frame& f = input_.frame;
  const double stamp = f.stamp_s;
  // Only the stamp and the pose are this frame's; the buffers may hold an earlier frame's.
  f.descriptors.clear();
  f.keypoints.clear();
  f.depth_codec = ImageCodec::kNone;
  f.depth.clear();
  TextLine words(image_words_, sizeof image_words_);
  ImageRefusal why = ImageRefusal::kCount;
  if (image_reader_.ReadColour(colour_path, &f, &why, &words) &&
      !image_reader_.CheckDepth(depth_path, note, &why, &words)) {
    f.colour_codec = ImageCodec::kNone;  // refused: the tick runs on odometry alone
    f.colour.clear();
  }
  ++counters_.image_frames;
  if (!TickStaged()) return;
  if (why != ImageRefusal::kCount) {
    RefuseImage(why, stamp, words.view());
  } else if (loop_->last_record().image_refused) {
    ReportFrontEndRefusal(stamp, colour_path);
  }
  (void)loop_->Idle();
}

void Daemon::ReportFrontEndRefusal(double stamp_s, std::string_view colour_path) {
  // The front-end's words start with the loop's own frame number ("frame 7: colour image ..."),
  // which means nothing to the robot: the file's path says which frame.
  std::string_view error = loop_->last_frame_error().message();
  if (error.rfind("frame ", 0) == 0) {
    const std::size_t colon = error.find(": ");
    if (colon != std::string_view::npos) error.remove_prefix(colon + 2);
  }
  TextLine words(image_words_, sizeof image_words_);
  words.Str(colour_path).Str(": ").Str(error);
  RefuseImage(ImageRefusal::kFrontEnd, stamp_s, words.view());
}

void Daemon::RefuseImage(ImageRefusal reason, double stamp_s, std::string_view words) {
  image_refusals_.Add(reason);
  const std::uint64_t count = image_refusals_[reason];
  if (count > 10 && !IsPowerOfTwo(count)) return;  // rate limit: 1..10, then 16, 32, 64, ...
  TextLine t(diag_, sizeof diag_);
  t.Str("zonemapd: input line ").U64(counters_.lines).Str(" (stamp ").Fixed(stamp_s, 6);
  t.Str("): image refused, ran on odometry (").Str(ImageRefusalName(reason)).Str("): ").Str(words);
  t.Str(" [").U64(count).Str(" so far");
  if (count == 10) t.Str("; further ones reported at powers of two");
  t.Str("]\n");
  if (t.ok()) Diagnose(t.view());
}

bool Daemon::Waiting() {
  if (fd_reader_) return fd_reader_->Waiting();
  if (udp_) return udp_->Waiting();
  return false;  // a recorded replay has no arrival times
}

void Daemon::AfterTick(const TickRecord& r) {
  const std::string_view line = publisher_.Publish(r);
  ++counters_.status_frames[static_cast<int>(publisher_.tracker().status())];
  if (!line.empty()) {
    Emit(line);
    ++counters_.pose_lines;
  }
}

void Daemon::HandleRoute() {
  const auto waypoints = static_cast<std::uint64_t>(input_.waypoints.size());
  bool ok = gate_->AcceptRoute(input_.waypoints);
  if (!ok) {
    Refuse(RejectReason::kRouteOutsideMap, RejectRule(RejectReason::kRouteOutsideMap), 0);
  } else if (!loop_->SetRoute(input_.waypoints)) {
    ok = false;
    Refuse(RejectReason::kRouteTooLong, "the route crosses more zones than reserved", 0);
  }
  if (ok) {
    ++counters_.routes_accepted;
  } else {
    ++counters_.routes_rejected;
  }
  const std::span<const ZoneId> zones = ok ? loop_->route() : std::span<const ZoneId>();
  Emit({out_.data(), FormatRouteAck(ok, waypoints, zones, out_.data(), out_.size())});
}

void Daemon::HandleBudget(std::uint64_t requested) {
  const std::uint32_t before = loop_->k_max();
  const BudgetChange c = loop_->SetBudget(requested);
  if (requested != 0) ++counters_.budget_changes;
  counters_.k_max_min = std::min(counters_.k_max_min, c.k_max);
  Emit({out_.data(), FormatBudgetAck(BudgetOutcomeName(c.outcome), c.requested, c.k_max,
                                     c.resident, c.unloaded, out_.data(), out_.size())});
  TextLine t(diag_, sizeof diag_);
  t.Str("zonemapd: budget ").U64(requested).Str(": K_max ").U64(before).Str(" -> ").U64(c.k_max);
  t.Str(" (").Str(BudgetOutcomeName(c.outcome)).Str("), ").U64(c.unloaded);
  t.Str(" keyframes unloaded, ").U64(c.resident).Str(" resident\n");
  if (t.ok()) Diagnose(t.view());
}

void Daemon::Refuse(RejectReason reason, const char* what, std::size_t column) {
  rejects_.Add(reason);
  staged_.set_malformed_lines(rejects_.total);
  const std::uint64_t count = rejects_[reason];
  if (count > 10 && !IsPowerOfTwo(count)) return;  // rate limit: 1..10, then 16, 32, 64, ...
  TextLine t(diag_, sizeof diag_);
  t.Str("zonemapd: input line ").U64(counters_.lines).Str(" refused (").Str(RejectReasonName(reason));
  t.Str("): ").Str(what);
  if (column != 0) t.Str(" at column ").U64(column);
  t.Str(" [").U64(count).Str(" so far");
  if (count == 10) t.Str("; further ones reported at powers of two");
  t.Str("]\n");
  if (t.ok()) Diagnose(t.view());
}

void Daemon::Emit(std::string_view bytes) {
  if (bytes.empty()) return;
  if (options_.pose_fd >= 0 && !WriteAll(options_.pose_fd, bytes)) {
    // The robot closed its end (EPIPE: zonemapd ignores SIGPIPE) or the fd broke: count it, say
    // it once, stop writing there, keep localizing (the estimate and telemetry still record).
    ++counters_.output_errors;
    options_.pose_fd = -1;
    Diagnose("zonemapd: writing pose lines failed; no further pose lines on that output\n");
  }
  if (udp_ && !udp_->Reply(bytes)) ++counters_.udp_reply_errors;
}

void Daemon::Diagnose(std::string_view text) {
  if (options_.diagnostics_fd >= 0) (void)WriteAll(options_.diagnostics_fd, text);
}

void Daemon::Flush() { publisher_.Flush(); }

nlohmann::json Daemon::Summary(bool interrupted) const {
  nlohmann::json s = ToJson(LoopSummary(*loop_, interrupted));
  nlohmann::json by_reason = nlohmann::json::object();
  for (std::size_t i = 0; i < kRejectReasonCount; ++i) {
    by_reason[RejectReasonName(static_cast<RejectReason>(i))] = rejects_.by_reason[i];
  }
  s["malformed_lines"] = rejects_.total;
  s["malformed_by_reason"] = by_reason;
  s["input"] = {{"lines", counters_.lines}, {"frames", counters_.frames}};
  nlohmann::json refused = nlohmann::json::object();
  for (std::size_t i = 0; i < kImageRefusalCount; ++i) {
    refused[ImageRefusalName(static_cast<ImageRefusal>(i))] = image_refusals_.by_reason[i];
  }
  s["images"] = {{"enabled", images_.max_colour_bytes > 0},
                 {"width", images_.width},
                 {"height", images_.height},
                 {"reserve_bytes", images_.max_colour_bytes},
                 {"frames", counters_.image_frames},
                 {"refused", image_refusals_.total},
                 {"refused_by_reason", refused},
                 {"frames_without_odometry",
                  camera_files_ != nullptr ? camera_files_->frames_without_odometry() : 0}};
  s["control"] = {{"routes_accepted", counters_.routes_accepted},
                  {"routes_rejected", counters_.routes_rejected},
                  {"route_zones", loop_->route().size()},
                  {"budget_changes", counters_.budget_changes},
                  {"k_max_min", counters_.k_max_min},
                  {"k_max_end", loop_->k_max()}};
  s["output"] = {{"pose_protocol_version", kPoseProtocolVersion},
                 {"pose_lines", counters_.pose_lines},
                 {"write_errors", counters_.output_errors},
                 {"udp_reply_errors", counters_.udp_reply_errors}};
  s["localization_status_frames"] = {
      {"localized", counters_.status_frames[static_cast<int>(LocalizationStatus::kLocalized)]},
      {"dead_reckoning",
       counters_.status_frames[static_cast<int>(LocalizationStatus::kDeadReckoning)]},
      {"lost", counters_.status_frames[static_cast<int>(LocalizationStatus::kLost)]}};
  return s;
}

}  // namespace zm
