// Camera frames as image files (see image_files.h).
#include "runtime/image_files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <string>

namespace zm {
namespace {

// The file's first bytes: PNG's 8-byte signature, JPEG's SOI marker and the next marker's 0xFF.
constexpr unsigned char kPngMagic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
constexpr unsigned char kJpegMagic[3] = {0xFF, 0xD8, 0xFF};

bool StartsWith(const std::vector<std::byte>& bytes, const unsigned char* magic, std::size_t n) {
  return bytes.size() >= n && std::memcmp(bytes.data(), magic, n) == 0;
}

// errno in words, untranslated: strerror() may go through gettext, which can allocate.
std::string_view ErrnoText() {
  const char* text = strerrordesc_np(errno);
  return text != nullptr ? text : "unknown error";
}

// Closes a descriptor on every return path.
struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

const char* ImageRefusalName(ImageRefusal reason) {
  switch (reason) {
    case ImageRefusal::kUnreadable:
      return "unreadable";
    case ImageRefusal::kTooLarge:
      return "too_large";
    case ImageRefusal::kNoDepth:
      return "no_depth";
    case ImageRefusal::kFrontEnd:
      return "front_end";
    case ImageRefusal::kCount:
      break;
  }
  return "unknown";
}

std::uint32_t MaxEncodedImageBytes(std::uint32_t width, std::uint32_t height) {
  const std::uint64_t bytes = 4ull * width * height + height + (64u << 10);
  return static_cast<std::uint32_t>(std::min<std::uint64_t>(bytes, 0xFFFFFFFFull));
}

Status CheckImageSize(const CameraIntrinsics& k, std::uint32_t width, std::uint32_t height) {
  const std::string map = std::to_string(k.width) + "x" + std::to_string(k.height);
  const std::string got = std::to_string(width) + "x" + std::to_string(height);
  if (width == 0 || height == 0 || width > 16384 || height > 16384) {
    return InvalidArgument("image size " + got + ": each side must be 1 to 16384 pixels");
  }
  if (k.width == 0 || k.height == 0) {
    return FailedPrecondition("the map has no camera size, so images of " + got +
                              " cannot be related to its keypoints");
  }
  // |w/W - h/H| <= 1/min(W, H), in integers: the same field of view to within a pixel.
  const std::uint64_t a = std::uint64_t{width} * k.height;
  const std::uint64_t b = std::uint64_t{height} * k.width;
  const std::uint64_t diff = a > b ? a - b : b - a;
  if (diff > std::max(k.width, k.height)) {
    return InvalidArgument("images of " + got + " are not a plain scale of the map camera's " +
                           map + " (another aspect ratio: another field of view)");
  }
  return Status::Ok();
}

bool ImageFileReader::Terminate(std::string_view path) {
  if (path.size() > kMaxImagePathBytes) return false;
  std::memcpy(path_, path.data(), path.size());
  path_[path.size()] = '\0';
  return true;
}

bool ImageFileReader::ReadColour(std::string_view path, Frame* frame, ImageRefusal* why,
                                 TextLine* message) {
  frame->colour_codec = ImageCodec::kNone;
  frame->colour.clear();
  // The message is written on failure only (the caller's line stays empty on success).
  const auto fail = [&](ImageRefusal r, std::string_view what, std::string_view detail = {}) {
    message->Str("colour image ").Str(path).Str(what).Str(detail);
    frame->colour.clear();
    *why = r;
    return false;
  };
  if (!Terminate(path)) return fail(ImageRefusal::kUnreadable, ": path longer than 4095 bytes");
  Fd f;
  f.fd = ::open(path_, O_RDONLY | O_CLOEXEC);
  if (f.fd < 0) return fail(ImageRefusal::kUnreadable, ": ", ErrnoText());
  struct stat st {};
  if (::fstat(f.fd, &st) != 0) return fail(ImageRefusal::kUnreadable, ": ", ErrnoText());
  if (!S_ISREG(st.st_mode)) return fail(ImageRefusal::kUnreadable, ": not a regular file");
  if (st.st_size == 0) return fail(ImageRefusal::kUnreadable, " is empty (0 bytes)");
  const auto size = static_cast<std::uint64_t>(st.st_size);
  if (size > max_colour_bytes_ || size > frame->colour.capacity()) {
    message->Str("colour image ")
        .Str(path)
        .Str(" is ")
        .U64(size)
        .Str(" bytes, above the reserve of ");
    message->U64(max_colour_bytes_).Str(" bytes for ").U64(width_).Char('x').U64(height_);
    message->Str(" images");
    *why = ImageRefusal::kTooLarge;
    return false;
  }
  frame->colour.resize(size);  // within the reserve: no allocation
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::read(f.fd, frame->colour.data() + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return fail(ImageRefusal::kUnreadable, ": ", ErrnoText());
    if (n == 0) break;  // the file shrank while it was read: what is there goes to the decoder
    done += static_cast<std::size_t>(n);
  }
  frame->colour.resize(done);
  if (StartsWith(frame->colour, kPngMagic, sizeof kPngMagic)) {
    frame->colour_codec = ImageCodec::kPng;
  } else if (StartsWith(frame->colour, kJpegMagic, sizeof kJpegMagic)) {
    frame->colour_codec = ImageCodec::kJpeg;
  } else {
    message->Str("colour image ")
        .Str(path)
        .Str(" (")
        .U64(done)
        .Str(" bytes) is neither PNG nor JPEG");
    *why = ImageRefusal::kUnreadable;
    frame->colour.clear();
    return false;
  }
  return true;
}

bool ImageFileReader::CheckDepth(std::string_view path, std::string_view note, ImageRefusal* why,
                                 TextLine* message) {
  if (path == "-") return true;
  // The message and the reason are written on failure only.
  const auto fail = [&](std::string_view what, std::string_view detail = {}) {
    if (path.empty()) {
      message->Str("no depth image for the frame");
      if (!note.empty()) message->Str(" (").Str(note).Char(')');
    } else {
      message->Str("depth image ").Str(path).Str(what).Str(detail);
    }
    *why = ImageRefusal::kNoDepth;
    return false;
  };
  if (path.empty()) return fail({});
  if (!Terminate(path)) return fail(": path longer than 4095 bytes");
  struct stat st {};
  if (::stat(path_, &st) != 0) return fail(": ", ErrnoText());
  if (!S_ISREG(st.st_mode)) return fail(": not a regular file");
  if (st.st_size == 0) return fail(" is empty (0 bytes)");
  return true;
}

}  // namespace zm
