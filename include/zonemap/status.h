// zonemap public API: errors are values.
//
// Every call that can fail returns a Status or a Result<T>. Nothing in the public API throws:
// the library turns what the standard library, SQLite or OpenCV report into a Status at the
// edge where it calls them. A Status carries a code and one human-readable line naming the thing
// and the limit ("keyframe 17 appears twice", "map.slot_bytes 4096 is smaller than the largest
// keyframe (2200000 bytes)").
//
// One definition: these are the library's own error types too (zm::Status in lib/common/status.h
// is this one), so a message reads the same from zonemapd, the command line and the API.
// StatusCodeName, ToString and Annotate are defined in the library (libzonemap); the rest is
// inline. Standard library only.
//
// Cost: an OK Status holds an empty std::string and never allocates; only an error allocates its
// message.
#pragma once

#include <cassert>
#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace zonemap {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,     // bad input from the caller or a file
  kNotFound,            // a named thing does not exist
  kCorrupt,             // data on disk is damaged or inconsistent
  kOutOfRange,          // a size or count beyond a limit (slot size, budget)
  kResourceExhausted,   // out of memory, arena full
  kFailedPrecondition,  // wrong state (a call out of order, a map without zones, a schema)
  kIoError,             // the OS or SQLite refused an operation
  kUnsupported,         // valid but not handled by this build
  kInternal,            // a bug in zonemap: please report it
};

// "ok", "invalid argument", ..., "I/O error", "unsupported", "internal error".
[[nodiscard]] std::string_view StatusCodeName(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}
  static Status Ok() { return {}; }

  [[nodiscard]] bool ok() const { return code_ == StatusCode::kOk; }
  [[nodiscard]] StatusCode code() const { return code_; }
  [[nodiscard]] const std::string& message() const { return message_; }
  // "<code>: <message>", or "ok".
  [[nodiscard]] std::string ToString() const;
  // The same error with context in front ("loading zone 3: <message>"), code kept; ok stays ok.
  [[nodiscard]] Status Annotate(std::string_view context) const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

// A value or the Status saying why there is none.
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}        // NOLINT: implicit by design
  Result(Status status) : v_(std::move(status)) {  // NOLINT: implicit by design
    assert(!std::get<Status>(v_).ok() && "a Result needs a value or an error");
  }
  [[nodiscard]] bool ok() const { return std::holds_alternative<T>(v_); }
  // Ok when there is a value.
  [[nodiscard]] const Status& status() const {
    static const Status kOkStatus;
    return ok() ? kOkStatus : std::get<Status>(v_);
  }
  [[nodiscard]] T& value() & { assert(ok()); return std::get<T>(v_); }
  [[nodiscard]] const T& value() const& { assert(ok()); return std::get<T>(v_); }
  [[nodiscard]] T&& value() && { assert(ok()); return std::get<T>(std::move(v_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

 private:
  std::variant<T, Status> v_;
};

}  // namespace zonemap
