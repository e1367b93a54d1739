// TextLine: builds one protocol or diagnostic line in a caller-owned fixed buffer with
// std::to_chars, so formatting a pose line, an acknowledgement or a stderr diagnostic never
// allocates, never depends on the C locale (a robot configured for "1,5" still gets "1.5"), and
// never overflows: once the buffer is full every further append is dropped and ok() turns false,
// which the caller treats as "this line was not written" (counted, never truncated on the wire).
#pragma once

#include <charconv>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

namespace zm {

class TextLine {
 public:
  TextLine(char* buffer, std::size_t capacity) : buf_(buffer), cap_(capacity) {}

  TextLine& Str(std::string_view s) {
    if (!ok_ || s.size() > cap_ - len_) return Fail();
    if (s.empty()) return *this;  // an empty view may have no data (memcpy from null is UB)
    std::memcpy(buf_ + len_, s.data(), s.size());
    len_ += s.size();
    return *this;
  }
  TextLine& Char(char c) {
    if (!ok_ || len_ == cap_) return Fail();
    buf_[len_++] = c;
    return *this;
  }
  // A separating space, then the value (the protocol's tokens are space separated).
  TextLine& Sp() { return Char(' '); }
  TextLine& U64(std::uint64_t v) { return Conv(v); }
  TextLine& I64(std::int64_t v) { return Conv(v); }
  // Fixed notation with `decimals` digits after the point ("12.500000").
  TextLine& Fixed(double v, int decimals) {
    if (!ok_) return *this;
    const auto r = std::to_chars(buf_ + len_, buf_ + cap_, v, std::chars_format::fixed, decimals);
    return Advance(r);
  }
  // Shortest of fixed/scientific with `digits` significant digits ("0.0025", "1.5e-07").
  TextLine& General(double v, int digits) {
    if (!ok_) return *this;
    const auto r = std::to_chars(buf_ + len_, buf_ + cap_, v, std::chars_format::general, digits);
    return Advance(r);
  }

  [[nodiscard]] bool ok() const { return ok_; }
  [[nodiscard]] std::size_t size() const { return len_; }
  [[nodiscard]] std::string_view view() const { return {buf_, len_}; }

 private:
  template <class T>
  TextLine& Conv(T v) {
    if (!ok_) return *this;
    return Advance(std::to_chars(buf_ + len_, buf_ + cap_, v));
  }
  TextLine& Advance(std::to_chars_result r) {
    if (r.ec != std::errc()) return Fail();
    len_ = static_cast<std::size_t>(r.ptr - buf_);
    return *this;
  }
  TextLine& Fail() {
    ok_ = false;
    return *this;
  }

  char* buf_;
  std::size_t cap_;
  std::size_t len_ = 0;
  bool ok_ = true;
};

}  // namespace zm
