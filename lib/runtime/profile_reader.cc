// The strict profile reader over toml++ (see profile_reader.h).
#include "runtime/profile_reader.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#ifndef ZM_PROFILES_DIR
#define ZM_PROFILES_DIR ""
#endif

namespace zm {
namespace {

std::string TypeName(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::table: return "table";
    case toml::node_type::array: return "array";
    case toml::node_type::string: return "string";
    case toml::node_type::integer: return "integer";
    case toml::node_type::floating_point: return "float";
    case toml::node_type::boolean: return "boolean";
    case toml::node_type::date: return "date";
    case toml::node_type::time: return "time";
    case toml::node_type::date_time: return "date-time";
    default: return "nothing";
  }
}

std::string ExecutableDir() {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : exe.parent_path().string();
}

}  // namespace

TableReader::TableReader(const toml::table* table, std::string prefix, const std::string* file,
                         Status* error)
    : table_(table), prefix_(std::move(prefix)), file_(file), error_(error) {}

void TableReader::String(std::string_view key, std::string& out) {
  const toml::node* n = Find(key);
  if (n == nullptr) return;
  if (!n->is_string()) return Fail(*n, key, "must be a string, got " + TypeName(*n));
  out = n->as_string()->get();
}

void TableReader::Bool(std::string_view key, bool& out) {
  const toml::node* n = Find(key);
  if (n == nullptr) return;
  if (!n->is_boolean()) return Fail(*n, key, "must be true or false, got " + TypeName(*n));
  out = n->as_boolean()->get();
}

void TableReader::U64(std::string_view key, std::uint64_t& out, std::uint64_t min,
                      std::uint64_t max) {
  const toml::node* n = Find(key);
  if (n == nullptr) return;
  if (!n->is_integer()) return Fail(*n, key, "must be an integer, got " + TypeName(*n));
  const std::int64_t v = n->as_integer()->get();
  if (v < 0 || static_cast<std::uint64_t>(v) < min || static_cast<std::uint64_t>(v) > max) {
    return Fail(*n, key, "is " + std::to_string(v) + ", must be in [" + std::to_string(min) +
                             ", " + std::to_string(max) + "]");
  }
  out = static_cast<std::uint64_t>(v);
}

void TableReader::U32(std::string_view key, std::uint32_t& out, std::uint32_t min,
                      std::uint32_t max) {
  std::uint64_t v = out;
  U64(key, v, min, max);
  out = static_cast<std::uint32_t>(v);
}

void TableReader::Bytes(std::string_view key, std::uint64_t& out) {
  const toml::node* n = Find(key);
  if (n == nullptr) return;
  if (n->is_integer()) {
    const std::int64_t v = n->as_integer()->get();
    if (v < 0) return Fail(*n, key, "is negative (" + std::to_string(v) + ")");
    out = static_cast<std::uint64_t>(v);
    return;
  }
  if (n->is_string()) {
    Result<std::uint64_t> b = ParseBytes(n->as_string()->get());
    if (!b.ok()) return Fail(*n, key, b.status().message());
    out = *b;
    return;
  }
  Fail(*n, key, "must be bytes (an integer or a string such as \"1.5GiB\"), got " + TypeName(*n));
}

void TableReader::Double(std::string_view key, double& out, double min, double max) {
  const toml::node* n = Find(key);
  if (n == nullptr) return;
  double v = 0.0;
  if (n->is_floating_point()) {
    v = n->as_floating_point()->get();
  } else if (n->is_integer()) {
    v = static_cast<double>(n->as_integer()->get());
  } else {
    return Fail(*n, key, "must be a number, got " + TypeName(*n));
  }
  if (!std::isfinite(v) || v < min || v > max) {
    std::ostringstream s;
    s << "is " << v << ", must be in [" << min << ", " << max << "]";
    return Fail(*n, key, s.str());
  }
  out = v;
}

TableReader TableReader::Sub(std::string_view key) {
  const toml::node* n = Find(key);
  if (n != nullptr && !n->is_table()) {
    Fail(*n, key, "must be a table, got " + TypeName(*n));
    n = nullptr;
  }
  return {n == nullptr ? nullptr : n->as_table(), FullKey(key), file_, error_};
}

void TableReader::Finish() {
  if (table_ == nullptr || !error_->ok()) return;
  for (auto&& [k, v] : *table_) {
    if (seen_.count(std::string(k.str())) == 0) {
      *error_ = InvalidArgument(Where(v) + "unknown key '" + FullKey(k.str()) + "'");
      return;
    }
  }
}

void TableReader::FailKey(std::string_view key, const std::string& message) {
  const toml::node* n = table_ == nullptr ? nullptr : table_->get(key);
  if (n != nullptr) {
    Fail(*n, key, message);
  } else if (error_->ok()) {
    *error_ = InvalidArgument(*file_ + ": key '" + FullKey(key) + "' " + message);
  }
}

const toml::node* TableReader::Find(std::string_view key) {
  seen_.insert(std::string(key));
  if (table_ == nullptr || !error_->ok()) return nullptr;
  return table_->get(key);
}

std::string TableReader::FullKey(std::string_view key) const {
  return prefix_.empty() ? std::string(key) : prefix_ + "." + std::string(key);
}

std::string TableReader::Where(const toml::node& n) const {
  const auto& src = n.source();
  return *file_ + ":" + std::to_string(src.begin.line) + ": ";
}

void TableReader::Fail(const toml::node& n, std::string_view key, const std::string& message) {
  if (!error_->ok()) return;
  *error_ = InvalidArgument(Where(n) + "key '" + FullKey(key) + "' " + message);
}

ProfileDocument::ProfileDocument(ProfileDocument&&) noexcept = default;
ProfileDocument& ProfileDocument::operator=(ProfileDocument&&) noexcept = default;
ProfileDocument::~ProfileDocument() = default;

Result<ProfileDocument> ProfileDocument::Parse(std::string_view toml_text,
                                               const std::string& source) {
  ProfileDocument doc;
  doc.source_ = std::make_unique<std::string>(source);
  doc.table_ = std::make_unique<toml::table>();
  try {
    *doc.table_ = toml::parse(toml_text, source);
  } catch (const toml::parse_error& e) {
    const auto& where = e.source().begin;
    return InvalidArgument(source + ":" + std::to_string(where.line) + ": " +
                           std::string(e.description()));
  }
  doc.error_ = std::make_unique<Status>();
  doc.root_ = std::make_unique<TableReader>(doc.table_.get(), "", doc.source_.get(), doc.error_.get());
  return doc;
}

Result<ProfileDocument> ProfileDocument::Load(const std::string& name_or_path) {
  std::string path;
  const bool is_path = name_or_path.find('/') != std::string::npos ||
                       (name_or_path.size() > 5 &&
                        name_or_path.compare(name_or_path.size() - 5, 5, ".toml") == 0);
  if (is_path) {
    path = name_or_path;
  } else {
    if (name_or_path.empty()) return InvalidArgument("empty profile name");
    const std::vector<std::string> dirs = ProfileSearchDirs();
    for (const std::string& d : dirs) {
      std::error_code ec;
      const std::string candidate = d + "/" + name_or_path + ".toml";
      if (std::filesystem::is_regular_file(candidate, ec)) {
        path = std::filesystem::weakly_canonical(candidate, ec).string();
        if (ec) path = candidate;
        break;
      }
    }
    if (path.empty()) {
      std::string searched;
      for (const std::string& d : dirs) searched += (searched.empty() ? "" : ", ") + d;
      return NotFound("profile '" + name_or_path + "' not found (searched " + searched +
                      "; set ZM_PROFILES_DIR)");
    }
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound("profile file '" + path + "' cannot be opened");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return IoError("profile file '" + path + "': read failed");
  return Parse(text.str(), path);
}

void ProfileDocument::SkipSection(std::string_view name) {
  // Reading the key marks it as known without consuming what is inside.
  (void)root_->Sub(name);
}

Status ProfileDocument::Finish() {
  root_->Finish();
  return *error_;
}

std::vector<std::string> ProfileSearchDirs() {
  std::vector<std::string> dirs;
  if (const char* env = std::getenv("ZM_PROFILES_DIR"); env != nullptr && *env != '\0') {
    dirs.emplace_back(env);
  }
  // An installed program's own profiles come before the build's source tree: a package built on
  // a machine that still has its checkout must not read that checkout's files.
  const std::string exe = ExecutableDir();
  if (!exe.empty()) dirs.push_back(exe + "/../share/zonemap/profiles");
  if (std::string_view(ZM_PROFILES_DIR).size() > 0) dirs.emplace_back(ZM_PROFILES_DIR);
  if (!exe.empty()) {
    dirs.push_back(exe + "/../../profiles");
    dirs.push_back(exe + "/../../../profiles");
  }
  return dirs;
}

Result<std::uint64_t> ParseBytes(std::string_view text) {
  const std::string original(text);
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  std::size_t digits = 0;
  while (digits < text.size() &&
         ((text[digits] >= '0' && text[digits] <= '9') || text[digits] == '.')) {
    ++digits;
  }
  std::string_view number = text.substr(0, digits);
  std::string_view unit = text.substr(digits);
  while (!unit.empty() && unit.front() == ' ') unit.remove_prefix(1);
  if (number.empty()) return InvalidArgument("'" + original + "' is not a byte size");
  struct Unit {
    std::string_view name;
    double factor;
  };
  static constexpr std::array<Unit, 14> kUnits = {{
      {"", 1.0}, {"B", 1.0},
      {"K", 1024.0}, {"KiB", 1024.0}, {"M", 1048576.0}, {"MiB", 1048576.0},
      {"G", 1073741824.0}, {"GiB", 1073741824.0}, {"T", 1099511627776.0},
      {"TiB", 1099511627776.0},
      {"KB", 1e3}, {"MB", 1e6}, {"GB", 1e9}, {"TB", 1e12},
  }};
  const Unit* found = nullptr;
  for (const Unit& u : kUnits) {
    if (u.name == unit) found = &u;
  }
  if (found == nullptr) {
    return InvalidArgument("'" + original + "' has an unknown unit '" + std::string(unit) +
                           "' (B, K, M, G, T, KiB, MiB, GiB, TiB, KB, MB, GB, TB)");
  }
  if (number.find('.') != std::string_view::npos) {
    if (found->factor == 1.0) {
      return InvalidArgument("'" + original + "': a fractional byte count needs a unit");
    }
    const std::string n(number);
    char* end = nullptr;
    const double v = std::strtod(n.c_str(), &end);
    if (end != n.c_str() + n.size() || !std::isfinite(v)) {
      return InvalidArgument("'" + original + "' is not a byte size");
    }
    const double bytes = std::round(v * found->factor);
    if (bytes >= 1.8e19) return OutOfRange("'" + original + "' exceeds 2^64 bytes");
    return static_cast<std::uint64_t>(bytes);
  }
  std::uint64_t v = 0;
  const auto [ptr, ec] = std::from_chars(number.data(), number.data() + number.size(), v);
  if (ec != std::errc() || ptr != number.data() + number.size()) {
    return InvalidArgument("'" + original + "' is not a byte size");
  }
  const auto factor = static_cast<std::uint64_t>(found->factor);
  if (v != 0 && factor > std::numeric_limits<std::uint64_t>::max() / v) {
    return OutOfRange("'" + original + "' exceeds 2^64 bytes");
  }
  return v * factor;
}

}  // namespace zm
