// Parameters declared once, as PX4 declares its parameters (PARAM_DEFINE_* with their metadata):
// each tunable a user can set names itself, its default, its range and its help in ONE
// declaration, in the module that owns it. The command line (app/param_options.h, CLI11), the
// profile reader and the public API's checks take the default, the range and the help from that
// declaration instead of restating them.
//
//   // zones/annotate.h
//   inline constexpr Param<double> kDoorwayBandParam{
//       "band", 0.5, 0.0, 100.0, "doorway band: a keyframe this close to a neighbouring zone "
//       "joins it too (metres)"};
//   struct AnnotateOptions { double band_m = kDoorwayBandParam.default_value; };
//
// A parameter with a grammar of its own (MemoryThr's "N", "BYTES" or "N,BYTES") is a TextParam:
// its parser lives beside it and every entry point calls that parser.
#pragma once

#include <cstdint>
#include <sstream>
#include <string>
#include <string_view>
#include <type_traits>

#include "common/status.h"

namespace zm {

template <typename T>
struct Param {
  static_assert(std::is_arithmetic_v<T>);
  std::string_view name;  // the command line's flag without "--" (profile keys name their section)
  T default_value;
  T min;  // inclusive
  T max;  // inclusive
  std::string_view help;  // one line, without the default and the range (added where shown)

  // OK inside [min, max] (NaN never is); else an error naming the parameter, the value and the
  // range ("--band 200: must be 0 to 100").
  [[nodiscard]] Status Check(T value) const {
    if (value >= min && value <= max) return Status::Ok();
    std::ostringstream m;
    m << "--" << name << ' ' << +value << ": must be " << +min << " to " << +max;
    return OutOfRange(m.str());
  }

  // The help with the default and the range, as the command line shows it.
  [[nodiscard]] std::string HelpWithDefault() const {
    std::ostringstream m;
    m << help << " (default " << +default_value << "; " << +min << " to " << +max << ')';
    return m.str();
  }
};

// A parameter whose value is text with a grammar of its own; "" = not given (the default).
struct TextParam {
  std::string_view name;
  std::string_view help;
};

}  // namespace zm
