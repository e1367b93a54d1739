// Errors are values on library APIs (docs/style.md §5): a Status carries a code and one
// human-readable line that names the thing and the limit; Result<T> is a value or a Status.
// Nothing here throws. Constructing an error allocates its message; the OK path never does.
#pragma once

#include <cassert>
#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace zm {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,    // bad input from the caller or a file
  kNotFound,           // a named thing does not exist
  kCorrupt,            // data on disk is damaged or inconsistent
  kOutOfRange,         // a size or count beyond a limit (slot size, budget)
  kResourceExhausted,  // out of memory, arena full
  kFailedPrecondition, // wrong schema version, wrong state
  kIoError,            // the OS or SQLite refused an operation
  kUnsupported,        // valid but not handled by this build
  kInternal,           // a bug
};

[[nodiscard]] std::string_view StatusCodeName(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}
  static Status Ok() { return {}; }

  [[nodiscard]] bool ok() const { return code_ == StatusCode::kOk; }
  [[nodiscard]] StatusCode code() const { return code_; }
  [[nodiscard]] const std::string& message() const { return message_; }
  // "<code>: <message>", for logs and the CLI's one-line errors.
  [[nodiscard]] std::string ToString() const;
  // Prefixes context ("loading zone 3: ...") while keeping the code.
  [[nodiscard]] Status Annotate(std::string_view context) const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status InvalidArgument(std::string m) { return {StatusCode::kInvalidArgument, std::move(m)}; }
inline Status NotFound(std::string m) { return {StatusCode::kNotFound, std::move(m)}; }
inline Status Corrupt(std::string m) { return {StatusCode::kCorrupt, std::move(m)}; }
inline Status OutOfRange(std::string m) { return {StatusCode::kOutOfRange, std::move(m)}; }
inline Status ResourceExhausted(std::string m) { return {StatusCode::kResourceExhausted, std::move(m)}; }
inline Status FailedPrecondition(std::string m) { return {StatusCode::kFailedPrecondition, std::move(m)}; }
inline Status IoError(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
inline Status Unsupported(std::string m) { return {StatusCode::kUnsupported, std::move(m)}; }
inline Status Internal(std::string m) { return {StatusCode::kInternal, std::move(m)}; }

template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}            // NOLINT: implicit by design
  Result(Status status) : v_(std::move(status)) {      // NOLINT: implicit by design
    assert(!std::get<Status>(v_).ok() && "Result needs a value or an error");
  }
  [[nodiscard]] bool ok() const { return std::holds_alternative<T>(v_); }
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

}  // namespace zm

// Returns the Status of `expr` from the enclosing function if it is an error.
#define ZM_RETURN_IF_ERROR(expr)                   \
  do {                                             \
    ::zm::Status zm_status_ = (expr);              \
    if (!zm_status_.ok()) return zm_status_;       \
  } while (false)

#define ZM_CONCAT_INNER_(a, b) a##b
#define ZM_CONCAT_(a, b) ZM_CONCAT_INNER_(a, b)
// ZM_ASSIGN_OR_RETURN(auto x, MakeX()); returns the error or binds the value.
#define ZM_ASSIGN_OR_RETURN(decl, expr) \
  ZM_ASSIGN_OR_RETURN_IMPL_(ZM_CONCAT_(zm_result_, __LINE__), decl, expr)
#define ZM_ASSIGN_OR_RETURN_IMPL_(tmp, decl, expr) \
  auto tmp = (expr);                               \
  if (!tmp.ok()) return tmp.status();              \
  decl = std::move(tmp).value()
