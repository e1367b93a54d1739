// Kernel control files (cgroupfs, sysfs, procfs), read and written the way those interfaces
// expect: read whole, written with one write(2). The cgroup and the swap device use them (the
// weights cache only ErrnoText), so an error reads the same from each: it names the file, the
// value and errno's text, after the caller's own prefix (`who`, e.g. "cgroup").
#pragma once

#include <string>
#include <string_view>

#include "common/status.h"

namespace zm {

// errno's text ("No such file or directory").
[[nodiscard]] std::string ErrnoText(int err);

[[nodiscard]] Result<std::string> ReadControlFile(const std::string& path,
                                                  std::string_view who = {});

// `what` says what the value is (e.g. "2.0 GiB" beside a byte count), shown in the error only.
[[nodiscard]] Status WriteControlFile(const std::string& path, const std::string& value,
                                      std::string_view who = {}, std::string_view what = {});

[[nodiscard]] bool PathExists(const std::string& path);

}  // namespace zm
