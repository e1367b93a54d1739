// Errors are values on library APIs (docs/style.md §5): a Status carries a code and one
// human-readable line that names the thing and the limit; Result<T> is a value or a Status.
// Nothing here throws. Constructing an error allocates its message; the OK path never does.
//
// The types are the public API's (include/zonemap/status.h, installed): one definition, so the
// core's errors reach an API caller as they are and read the same everywhere. This header adds
// what only the core uses: the constructors by code and the early-return macros.
#pragma once

#include <string>
#include <utility>

#include "zonemap/status.h"

namespace zm {

using zonemap::Result;
using zonemap::Status;
using zonemap::StatusCode;
using zonemap::StatusCodeName;

inline Status InvalidArgument(std::string m) { return {StatusCode::kInvalidArgument, std::move(m)}; }
inline Status NotFound(std::string m) { return {StatusCode::kNotFound, std::move(m)}; }
inline Status Corrupt(std::string m) { return {StatusCode::kCorrupt, std::move(m)}; }
inline Status OutOfRange(std::string m) { return {StatusCode::kOutOfRange, std::move(m)}; }
inline Status ResourceExhausted(std::string m) { return {StatusCode::kResourceExhausted, std::move(m)}; }
inline Status FailedPrecondition(std::string m) { return {StatusCode::kFailedPrecondition, std::move(m)}; }
inline Status IoError(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
inline Status Unsupported(std::string m) { return {StatusCode::kUnsupported, std::move(m)}; }
inline Status Internal(std::string m) { return {StatusCode::kInternal, std::move(m)}; }

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
