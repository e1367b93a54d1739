// zonemapd's session: the robot's localization service around the tick loop, one input line at a
// time (issue 18). app/zonemapd.cc is this plus argument parsing and signals, so everything the
// daemon does per line is testable here (tests/runtime/daemon_test.cc drives it over pipes and
// UDP, counting every allocation).
//
// Step() reads one line of the live protocol (line_protocol.h) from stdin/a pipe or a UDP socket
// (or one frame of a recorded frames file, or of a recorded folder of camera files: --tum) and:
//   frame   -> the input gate (input_gate.h); refused: counted per reason, stderr, nothing
//              else; accepted: staged for the loop, one Tick(), then its record published
//              (tick_publisher.h): one pose line to the robot (pose_output.h: stdout, and for
//              UDP one datagram back to the sender), one ticks.jsonl line, one estimate.tum line;
//   image   -> the same gate; accepted: its colour file read into the frame's encoded colour
//              buffer (image_files.h), its depth file looked at, then staged and ticked as a
//              frame: the loop's front-end extracts its features. A frame whose images cannot
//              be used is still ticked, on odometry (the robot gets its pose line), and counted
//              per ImageRefusal with one stderr line naming the file and the limit;
//   route   -> waypoints checked against the map's extent, TickLoop::SetRoute, `ack route`;
//   budget  -> TickLoop::SetBudget, `ack budget`;
//   other   -> a counted malformed line (its reason), never fatal.
// Diagnostics go to stderr only (refusals: the first 10 of each reason, then at powers of two).
//
// Images (issue 26 §4): whether camera frames can come is decided in Create(), because the loop
// builds its front-end (and its frame scratch) and every frame buffer reserves room for an
// encoded image there: --tum and a frames file with images always; the live input when
// DaemonOptions::images says so (kAuto: the map has a vocabulary, i.e. it was built from pixels).
//
// Bounded forever: everything is allocated in Create() (buffers sized from --max-features and
// [input] max_route_waypoints, and the images' size); a warm Step() allocates nothing whatever
// the line (tested for every policy, operator new and malloc counted; image lines too, except
// the words of an image the front-end refuses); the state kept per tick is counters and
// StreamingStats, so memory after a month equals memory after a minute.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/status.h"
#include "mapdb/map_db.h"
#include "runtime/frame_source.h"
#include "runtime/frames_file.h"
#include "runtime/image_files.h"
#include "runtime/input_gate.h"
#include "runtime/line_input.h"
#include "runtime/line_protocol.h"
#include "runtime/pose_output.h"
#include "runtime/profile.h"
#include "runtime/tick_loop.h"
#include "runtime/tick_publisher.h"

namespace zm {

// Where the session reads: exactly one of these.
struct DaemonInput {
  enum class Kind { kFd, kUdp, kReplay, kCameraFiles };
  Kind kind = Kind::kFd;
  int fd = 0;                  // kFd: a stream of lines (not owned; 0 = stdin)
  std::uint16_t udp_port = 0;  // kUdp: 127.0.0.1:port (0 = any free port: see udp_port())
  std::string frames_path;     // kReplay: a recorded frames file (frames_file.h)
  // kCameraFiles: a recorded sequence of image files (zonemapd --tum: lib/tum/tum_replay.h);
  // not owned, outlives the session.
  CameraFileSource* camera_files = nullptr;
};

// Whether the live input (stdin, UDP) may carry `image` lines.
enum class DaemonImages {
  kAuto,  // when the map has a vocabulary (built from pixels: its keyframes hold ORB features)
  kOn,    // always (a map of ORB keyframes without a vocabulary)
  kOff,   // never: a host with its own front-end sends `frame` lines; nothing is reserved
};

struct DaemonOptions {
  std::uint32_t max_features = kMaxFeaturesParam.default_value;  // largest live frame accepted
  int pose_fd = 1;                    // hello, pose lines and acks (-1: none); not owned
  int diagnostics_fd = 2;             // refusals and changes (-1: none); not owned
  std::string telemetry_path;         // ticks.jsonl ("" = none)
  std::string estimate_path;          // estimate.tum ("" = none)
  DaemonImages images = DaemonImages::kAuto;  // `image` lines on the live input
  std::uint32_t image_width = 0;      // their size (0: the map camera's; else a plain scale of it)
  std::uint32_t image_height = 0;
};

// What the session counted (summary.json's "input", "control" and "output").
struct DaemonCounters {
  std::uint64_t lines = 0;            // input lines read (frames file: frames read)
  std::uint64_t frames = 0;           // frames that reached the loop
  std::uint64_t image_frames = 0;     // of which camera frames (image lines, --tum, a frames
                                      // file's images), refused ones included
  std::uint64_t routes_accepted = 0;
  std::uint64_t routes_rejected = 0;
  std::uint64_t budget_changes = 0;   // budget lines handled (any outcome)
  std::uint32_t k_max_min = 0;        // smallest K_max in force at any time
  std::uint64_t pose_lines = 0;       // pose lines written
  std::uint64_t output_errors = 0;    // writes to pose_fd that failed (then pose_fd is dropped)
  std::uint64_t udp_reply_errors = 0; // datagrams back to the robot that failed
  std::uint64_t status_frames[3] = {};  // frames per LocalizationStatus
};

// The session is its frames' InputProbe: the loop's idle part (queued zone loads between
// ticks) stops as soon as the robot's next line is waiting.
class Daemon final : private InputProbe {
 public:
  // Builds the loop over `map` (which must outlive the session) with the profile's options, the
  // input gate over the map's extent, the output buffers and files. Everything is allocated here.
  [[nodiscard]] static Result<std::unique_ptr<Daemon>> Create(const Profile& profile,
                                                              MapReader& map,
                                                              const DaemonInput& input,
                                                              const DaemonOptions& options);
  ~Daemon() override;
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  // The hello line (protocol version, policy, budget, limits): once, before the first Step().
  void Hello();
  // Handles one input line (or recorded frame). true: continue; false: the input ended (or
  // --max-ticks was reached). An error is fatal (the input failed); bad lines never are.
  [[nodiscard]] Result<bool> Step();
  // Flushes ticks.jsonl and estimate.tum.
  void Flush();
  // summary.json: the loop's totals (LoopSummary) plus the session's. Allocates: once, at exit.
  [[nodiscard]] nlohmann::json Summary(bool interrupted) const;

  [[nodiscard]] const TickLoop& loop() const { return *loop_; }
  [[nodiscard]] const RejectCounts& rejects() const { return rejects_; }
  // Image frames that ran on odometry, per reason.
  [[nodiscard]] const ImageRefusalCounts& image_refusals() const { return image_refusals_; }
  // The camera frames this session reads (all zero: none; see the file comment).
  [[nodiscard]] const FrameSource::Images& images() const { return images_; }
  [[nodiscard]] const DaemonCounters& counters() const { return counters_; }
  [[nodiscard]] const PoseTracker& tracker() const { return publisher_.tracker(); }
  [[nodiscard]] const InputGate& gate() const { return *gate_; }
  // The UDP port bound (kUdp), else 0.
  [[nodiscard]] std::uint16_t udp_port() const;

 private:
  Daemon(const Profile& profile, const DaemonOptions& options, std::uint32_t max_features);
  bool Waiting() override;
  void Dispatch(std::string_view line);
  [[nodiscard]] bool Admit(double quaternion_norm);
  [[nodiscard]] bool TickStaged();
  void HandleFrame(double quaternion_norm);
  void HandleImage(double quaternion_norm, std::string_view colour_path,
                   std::string_view depth_path, std::string_view note);
  void RefuseImage(ImageRefusal reason, double stamp_s, std::string_view words);
  void ReportFrontEndRefusal(double stamp_s, std::string_view colour_path);
  void HandleRoute();
  void HandleBudget(std::uint64_t requested);
  void AfterTick(const TickRecord& record);
  void Refuse(RejectReason reason, const char* what, std::size_t column);
  void Emit(std::string_view bytes);
  void Diagnose(std::string_view text);

  Profile profile_;
  DaemonOptions options_;
  std::unique_ptr<FdLineReader> fd_reader_;
  std::unique_ptr<UdpLineReader> udp_;
  std::unique_ptr<FrameReader> replay_;
  CameraFileSource* camera_files_ = nullptr;
  StagedFrameSource staged_;
  InputLine input_;
  std::unique_ptr<TickLoop> loop_;  // reads staged_: declared after it
  std::unique_ptr<InputGate> gate_;
  TickPublisher publisher_;          // pose line, telemetry, estimate: from the tick's record
  bool ended_ = false;                // Tick() reported the end (max_ticks)
  Status fatal_;                      // a Tick() error, returned by the next Step()
  std::vector<char> out_;             // one acknowledgement (the longest route ack)
  // One stderr line, and an image refusal's words (built before the tick, said after it): room
  // for two paths of kMaxImagePathBytes.
  char diag_[2 * kMaxImagePathBytes + 512] = {};
  char image_words_[2 * kMaxImagePathBytes + 512] = {};
  FrameSource::Images images_{};
  ImageFileReader image_reader_;
  ImageRefusalCounts image_refusals_;
  RejectCounts rejects_;
  DaemonCounters counters_;
};

}  // namespace zm
