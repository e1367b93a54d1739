// The command line's side of parameters declared once (common/param.h): a CLI11 option whose
// flag, default, range and help come from the declaration. Header-only and CLI11-only, so
// zonemapd (which links the on-device core alone) and `zonemap` share it.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "common/param.h"

namespace zm::app {

// --NAME VALUE, defaulting to the declaration's default, refused outside its range.
// The range check is the declaration's own (Param::Check), so the error reads the same
// everywhere: "--band: --band 60: must be 0 to 50".
template <typename T>
CLI::Option* AddParamOption(CLI::App& cmd, const Param<T>& param, T* value) {
  *value = param.default_value;
  CLI::Validator in_range(
      [param](std::string& text) -> std::string {
        T v{};
        if (!CLI::detail::lexical_cast(text, v)) return "'" + text + "' is not a number";
        const Status s = param.Check(v);
        return s.ok() ? std::string() : s.message();
      },
      "");
  return cmd.add_option("--" + std::string(param.name), *value, param.HelpWithDefault())
      ->check(in_range);
}

// --NAME TEXT (a grammar of its own, parsed by the parameter's owner); "" = not given.
inline CLI::Option* AddParamOption(CLI::App& cmd, const TextParam& param, std::string* value) {
  return cmd.add_option("--" + std::string(param.name), *value, std::string(param.help));
}

}  // namespace zm::app
