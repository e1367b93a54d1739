// The strict TOML reader behind device profiles: every accessor marks its key as read, and
// Finish() reports the first key nobody read as "unknown key 'map.slot_byte'". The first error
// wins and later calls are no-ops, so a caller reads a whole section and checks once.
//
// A profile file holds the core's sections (profile.h) and, optionally, sections that belong to
// other programs (the evaluation harness's [cotenant]). Each program reads the sections it owns
// from one ProfileDocument and declares the others as belonging elsewhere (SkipSection); any
// other top-level key is an error. toml++'s exceptions stop here and become a Status.
//
// Start-up only: this allocates freely and is never used inside the tick loop.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <toml++/toml.h>

#include "common/status.h"

namespace zm {

class TableReader {
 public:
  // `table` may be null (an absent section: every read keeps the default).
  TableReader(const toml::table* table, std::string prefix, const std::string* file,
              Status* error);

  void String(std::string_view key, std::string& out);
  void Bool(std::string_view key, bool& out);
  void U64(std::string_view key, std::uint64_t& out, std::uint64_t min = 0,
           std::uint64_t max = std::numeric_limits<std::uint64_t>::max());
  void U32(std::string_view key, std::uint32_t& out, std::uint32_t min = 0,
           std::uint32_t max = std::numeric_limits<std::uint32_t>::max());
  // An integer number of bytes or a string with a unit ("1.75GiB", "1.9GB"; ParseBytes).
  void Bytes(std::string_view key, std::uint64_t& out);
  void Double(std::string_view key, double& out, double min, double max);
  // A sub-table; absent means all defaults. A non-table value is an error.
  TableReader Sub(std::string_view key);
  // Every key of this table must have been read.
  void Finish();
  // Fails `key` with `message` (a value that parsed but is not acceptable).
  void FailKey(std::string_view key, const std::string& message);
  [[nodiscard]] bool ok() const { return error_->ok(); }

 private:
  const toml::node* Find(std::string_view key);
  [[nodiscard]] std::string FullKey(std::string_view key) const;
  [[nodiscard]] std::string Where(const toml::node& n) const;
  void Fail(const toml::node& n, std::string_view key, const std::string& message);

  const toml::table* table_;
  std::string prefix_;
  const std::string* file_;
  Status* error_;
  std::set<std::string> seen_;
};

class ProfileDocument {
 public:
  // A bare name ("orin-nano-8gb") resolves to <dir>/<name>.toml over ProfileSearchDirs();
  // anything containing '/' or ending in ".toml" is a path.
  [[nodiscard]] static Result<ProfileDocument> Load(const std::string& name_or_path);
  // `source` names the text in errors.
  [[nodiscard]] static Result<ProfileDocument> Parse(std::string_view toml_text,
                                                     const std::string& source);

  ProfileDocument(ProfileDocument&&) noexcept;
  ProfileDocument& operator=(ProfileDocument&&) noexcept;
  ~ProfileDocument();

  [[nodiscard]] const std::string& source() const { return *source_; }
  // The top-level table: read sections with root().Sub("map") etc.
  [[nodiscard]] TableReader& root() { return *root_; }
  // `name` is a section of another program: present or not, this one does not read it.
  void SkipSection(std::string_view name);
  // The first error of any reader, else an unknown top-level key, else Ok.
  [[nodiscard]] Status Finish();
  [[nodiscard]] const Status& error() const { return *error_; }

 private:
  ProfileDocument() = default;
  // Heap-held so the readers' pointers to them survive a move of the document.
  std::unique_ptr<std::string> source_;
  std::unique_ptr<toml::table> table_;
  std::unique_ptr<Status> error_;        // shared by every reader of this document
  std::unique_ptr<TableReader> root_;
};

// Directories searched for bare profile names, in order: $ZM_PROFILES_DIR, <executable
// dir>/../share/zonemap/profiles (an installed program's own), the build's source tree
// (compile-time ZM_PROFILES_DIR), then <executable dir>/../../profiles and
// <executable dir>/../../../profiles.
[[nodiscard]] std::vector<std::string> ProfileSearchDirs();

// "1.9GB", "512MiB", "4096", "2G": bytes. K/M/G and KiB/MiB/GiB are binary (1024^n), KB/MB/GB
// decimal (1000^n), B or nothing is bytes; a decimal fraction is allowed with a unit.
[[nodiscard]] Result<std::uint64_t> ParseBytes(std::string_view text);

}  // namespace zm
