#include "tum/tum_folder.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace zm {
namespace {

namespace fs = std::filesystem;

struct ListEntry {
  double stamp_s = 0.0;
  std::string path;
};

std::vector<std::string> Fields(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream in(line);
  std::string f;
  while (in >> f) out.push_back(f);
  return out;
}

bool ParseStamp(const std::string& text, double* out) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (errno != 0 || end == text.c_str() || *end != '\0' || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

Result<std::string> ReadText(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return IoError("cannot open " + path.string());
  // Through a stringstream, not istreambuf_iterator (GCC 12 aarch64 -O3 -Wnull-dereference).
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return IoError("cannot read " + path.string());
  return text.str();
}

// Calls fn(line_number, fields) for every line that is not empty or a comment.
template <class Fn>
void ForEachLine(const std::string& text, Fn&& fn) {
  std::istringstream in(text);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    fn(number, Fields(line));
  }
}

// A "stamp path" list (rgb.txt, depth.txt).
Result<std::vector<ListEntry>> ReadList(const fs::path& dir, const char* name, TumFolder* folder) {
  ZM_ASSIGN_OR_RETURN(const std::string text, ReadText(dir / name));
  std::vector<ListEntry> out;
  ForEachLine(text, [&](int number, const std::vector<std::string>& f) {
    ListEntry e;
    if (f.size() < 2 || !ParseStamp(f[0], &e.stamp_s)) {
      ++folder->malformed_lines;
      folder->problems.push_back(std::string(name) + " line " + std::to_string(number) +
                                 ": expected 'stamp path', skipped");
      return;
    }
    e.path = (dir / f[1]).string();
    out.push_back(std::move(e));
  });
  std::sort(out.begin(), out.end(),
            [](const ListEntry& a, const ListEntry& b) { return a.stamp_s < b.stamp_s; });
  return out;
}

bool UnderDepthFolder(const std::string& path) {
  return path.rfind("depth/", 0) == 0 || path.find("/depth/") != std::string::npos;
}

std::string Stamp(double s) {
  std::ostringstream o;
  o.precision(6);
  o << std::fixed << s;
  return o.str();
}

}  // namespace

Status ValidateTumFolderOptions(const TumFolderOptions& o) {
  if (!(o.max_stamp_difference_s > 0.0) || !std::isfinite(o.max_stamp_difference_s)) {
    return InvalidArgument("TUM association tolerance " + std::to_string(o.max_stamp_difference_s) +
                           " s: must be finite and > 0");
  }
  const CameraIntrinsics& c = o.camera;
  if (!(c.fx > 0.0) || !(c.fy > 0.0) || !std::isfinite(c.cx) || !std::isfinite(c.cy) ||
      c.width == 0 || c.height == 0) {
    return InvalidArgument("TUM camera fx " + std::to_string(c.fx) + " fy " + std::to_string(c.fy) +
                           " " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                           ": focal lengths and size must be > 0");
  }
  if (!(o.depth_units_per_m > 0.0) || !std::isfinite(o.depth_units_per_m)) {
    return InvalidArgument("TUM depth units per metre " + std::to_string(o.depth_units_per_m) +
                           ": must be finite and > 0");
  }
  return Status::Ok();
}

Result<TumFolder> ReadTumFolder(const std::string& dir_text, const TumFolderOptions& options) {
  ZM_RETURN_IF_ERROR(ValidateTumFolderOptions(options));
  const fs::path dir(dir_text);
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return NotFound("TUM folder " + dir_text + " is not a directory");
  TumFolder folder;
  folder.dir = dir_text;
  if (fs::exists(dir / "associations.txt", ec)) {
    folder.listing = "associations.txt";
    ZM_ASSIGN_OR_RETURN(const std::string text, ReadText(dir / "associations.txt"));
    ForEachLine(text, [&](int number, const std::vector<std::string>& f) {
      TumFrameFiles fr;
      if (f.size() < 4 || !ParseStamp(f[0], &fr.stamp_s) || !ParseStamp(f[2], &fr.depth_stamp_s)) {
        ++folder.malformed_lines;
        folder.problems.push_back("associations.txt line " + std::to_string(number) +
                                  ": expected 'rgb_stamp rgb_path depth_stamp depth_path', skipped");
        return;
      }
      fr.rgb_path = f[1];
      fr.depth_path = f[3];
      if (UnderDepthFolder(fr.rgb_path) && !UnderDepthFolder(fr.depth_path)) {  // depth first
        std::swap(fr.rgb_path, fr.depth_path);
        std::swap(fr.stamp_s, fr.depth_stamp_s);
      }
      fr.rgb_path = (dir / fr.rgb_path).string();
      fr.depth_path = (dir / fr.depth_path).string();
      ++folder.colour_entries;
      ++folder.depth_entries;
      folder.frames.push_back(std::move(fr));
    });
    std::sort(folder.frames.begin(), folder.frames.end(),
              [](const TumFrameFiles& a, const TumFrameFiles& b) { return a.stamp_s < b.stamp_s; });
  } else {
    if (!fs::exists(dir / "rgb.txt", ec) || !fs::exists(dir / "depth.txt", ec)) {
      return NotFound("TUM folder " + dir_text +
                      " has neither associations.txt nor both rgb.txt and depth.txt");
    }
    folder.listing = "rgb.txt + depth.txt";
    ZM_ASSIGN_OR_RETURN(const std::vector<ListEntry> rgb, ReadList(dir, "rgb.txt", &folder));
    ZM_ASSIGN_OR_RETURN(const std::vector<ListEntry> depth, ReadList(dir, "depth.txt", &folder));
    folder.colour_entries = static_cast<std::uint32_t>(rgb.size());
    folder.depth_entries = static_cast<std::uint32_t>(depth.size());
    for (const ListEntry& c : rgb) {
      // The nearest depth stamp: the first at or after c's, or the one before it.
      const auto after = std::lower_bound(
          depth.begin(), depth.end(), c.stamp_s,
          [](const ListEntry& e, double s) { return e.stamp_s < s; });
      const ListEntry* best = nullptr;
      if (after != depth.end()) best = &*after;
      if (after != depth.begin()) {
        const ListEntry* before = &*(after - 1);
        if (best == nullptr || c.stamp_s - before->stamp_s <= best->stamp_s - c.stamp_s) best = before;
      }
      if (best == nullptr || std::abs(best->stamp_s - c.stamp_s) > options.max_stamp_difference_s) {
        ++folder.gaps;
        folder.problems.push_back("colour frame " + Stamp(c.stamp_s) + ": no depth within " +
                                  std::to_string(options.max_stamp_difference_s) + " s (gap)");
        folder.gap_frames.push_back(TumFrameFiles{c.stamp_s, c.path, 0.0, ""});
        continue;
      }
      folder.frames.push_back(TumFrameFiles{c.stamp_s, c.path, best->stamp_s, best->path});
    }
  }
  if (folder.frames.empty()) {
    return FailedPrecondition("TUM folder " + dir_text + ": no colour frame with depth in " +
                              folder.listing + " (" + std::to_string(folder.colour_entries) +
                              " colour entries, " + std::to_string(folder.gaps) + " gaps, " +
                              std::to_string(folder.malformed_lines) + " malformed lines)");
  }
  return folder;
}

}  // namespace zm
