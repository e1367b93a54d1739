// Hospital-like floors. The footprint W x H (W = sqrt(2A)) is partitioned into axis-aligned
// rectangles, every edge a multiple of the grid resolution: a lobby at the west end (with rooms
// beside it), a main corridor along the middle (cut into segments, one per branch crossing),
// branch corridors every 12-16 m running north and south (cut into segments of at most
// max_corridor_segment_m), and between two branches two columns of patient rooms or wards whose
// doors open onto the nearer branch. Walls are centred on the rectangle edges, so the zone
// rectangles partition the building and every free cell lies in exactly one zone. Openings
// between corridor pieces are full width; rooms get one door. Beds, cabinets, pillars and a desk
// are furniture (occupied cells flagged in FloorMap::furniture).
//
// Floors share the x structure (lobby, branches) and the elevator (a 3 m room beside the lobby);
// rooms, wards and furniture differ per floor. Deterministic from the seed.
#include <algorithm>
#include <cmath>
#include <string>

#include "sim/building.h"
#include "sim/rng.h"

namespace zm::sim {
namespace {

struct Rect {
  double x0, y0, x1, y1;
};

enum class Side { kWest, kEast, kSouth, kNorth };

struct Space {
  Rect r;
  std::string kind;
  std::string name;
};

class FloorBuilder {
 public:
  FloorBuilder(FloorMap* floor, double res, double half_wall)
      : floor_(floor), res_(res), hw_(half_wall) {}

  // Cells whose centres lie in [x0, x1) x [y0, y1) get `value`.
  void Fill(const Rect& r, std::uint8_t value, bool furniture = false) {
    SimGrid& g = floor_->grid;
    const int c0 = std::max(0, static_cast<int>(std::lround((r.x0 - g.origin_m.x()) / res_)));
    const int c1 = std::min(g.cols, static_cast<int>(std::lround((r.x1 - g.origin_m.x()) / res_)));
    const int r0 = std::max(0, static_cast<int>(std::lround((r.y0 - g.origin_m.y()) / res_)));
    const int r1 = std::min(g.rows, static_cast<int>(std::lround((r.y1 - g.origin_m.y()) / res_)));
    for (int rr = r0; rr < r1; ++rr) {
      for (int cc = c0; cc < c1; ++cc) {
        g.cells[g.Index(cc, rr)] = value;
        floor_->furniture[g.Index(cc, rr)] = furniture ? 1 : 0;
      }
    }
  }
  void CarveInterior(const Rect& r) { Fill({r.x0 + hw_, r.y0 + hw_, r.x1 - hw_, r.y1 - hw_}, kCellFree); }
  // Opens the wall on the vertical line x = xb over y in [s0, s1) (or horizontal, y = yb).
  void OpenVertical(double xb, double s0, double s1) { Fill({xb - hw_, s0, xb + hw_, s1}, kCellFree); }
  void OpenHorizontal(double yb, double s0, double s1) { Fill({s0, yb - hw_, s1, yb + hw_}, kCellFree); }
  void Furniture(const Rect& r) { Fill(r, kCellOccupied, /*furniture=*/true); }

 private:
  FloorMap* floor_;
  double res_;
  double hw_;
};

}  // namespace

Result<Building> GenerateHospital(const HospitalOptions& o) {
  if (!(o.area_m2 >= 300.0 && o.area_m2 <= 200000.0)) {
    return InvalidArgument("hospital area " + std::to_string(o.area_m2) +
                           " m2 is outside [300, 200000] m2");
  }
  if (o.floors < 1 || o.floors > 20) {
    return InvalidArgument("hospital floors " + std::to_string(o.floors) + " is outside [1, 20]");
  }
  if (!(o.resolution_m >= 0.02 && o.resolution_m <= 0.2)) {
    return InvalidArgument("grid resolution " + std::to_string(o.resolution_m) +
                           " m is outside [0.02, 0.2] m");
  }
  if (!(o.door_width_m >= 0.8 && o.door_width_m <= 3.0) ||
      !(o.corridor_width_m >= 1.5 && o.corridor_width_m <= 6.0) ||
      !(o.branch_width_m >= 1.5 && o.branch_width_m <= 6.0) ||
      !(o.wall_thickness_m > 0.0 && o.wall_thickness_m <= 0.5) ||
      !(o.max_corridor_segment_m >= 4.0)) {
    return InvalidArgument(
        "hospital geometry out of range: door [0.8, 3] m, corridors [1.5, 6] m, walls (0, 0.5] m, "
        "corridor segments >= 4 m");
  }
  const double res = o.resolution_m;
  const auto snap = [res](double v) { return std::round(v / res) * res; };
  const double hw = std::max(res, snap(o.wall_thickness_m / 2.0));
  Rng layout_rng(o.seed, 0);

  const double W = snap(std::sqrt(2.0 * o.area_m2));
  const double H = snap(o.area_m2 / W);
  const double cw = snap(o.corridor_width_m), bw = snap(o.branch_width_m);
  const double ym0 = snap(H / 2.0 - cw / 2.0), ym1 = ym0 + cw;
  const double lobby_w = snap(std::clamp(0.15 * W, 8.0, 24.0));
  double ly0 = snap(std::max(0.0, H / 2.0 - std::clamp(0.4 * H, cw + 4.0, H) / 2.0));
  double ly1 = snap(std::min(H, H - ly0));
  if (ly0 < 3.0) ly0 = 0.0;
  if (H - ly1 < 3.0) ly1 = H;
  if (o.floors > 1 && ly1 >= H) {
    if (H - ym1 < 6.0) return InvalidArgument("hospital area too small for an elevator; use >= 600 m2");
    ly1 = snap(H - 3.5);
  }

  // The x structure shared by every floor: branch corridors and room columns.
  struct Column {
    double x0, x1;
    Side door;  // the branch the rooms open onto
  };
  std::vector<Rect> branches;  // full height, split later
  std::vector<Column> columns;
  std::vector<double> main_cuts;  // x positions where the main corridor is cut
  {
    double x = lobby_w;
    while (true) {
      double rem = W - x;
      const double bw_here = rem - bw < 3.0 ? rem : bw;
      branches.push_back({x, 0.0, x + bw_here, H});
      x += bw_here;
      rem = W - x;
      if (rem <= 1e-9) break;
      if (rem < 2 * 5.0 + bw + 4.0) {
        columns.push_back({x, W, Side::kWest});
        break;
      }
      const double d = snap(std::min(layout_rng.Uniform(5.0, 7.0), (rem - bw - 4.0) / 2.0));
      columns.push_back({x, x + d, Side::kWest});
      columns.push_back({x + d, x + 2 * d, Side::kEast});
      main_cuts.push_back(x + d);
      x += 2 * d;
    }
  }

  Building b;
  b.kind = "hospital";
  b.area_m2 = W * H;
  const double margin = 1.0;
  const int cols = static_cast<int>(std::lround((W + 2 * margin) / res));
  const int rows = static_cast<int>(std::lround((H + 2 * margin) / res));
  for (int f = 0; f < o.floors; ++f) {
    Rng rng(o.seed, 100 + static_cast<std::uint64_t>(f));
    FloorMap floor;
    floor.grid = SimGrid::Filled(cols, rows, res, Eigen::Vector2d(-margin, -margin), kCellUnknown);
    floor.furniture.assign(floor.grid.cells.size(), 0);
    floor.z_m = f * b.floor_height_m;
    FloorBuilder fb(&floor, res, hw);
    fb.Fill({0.0, 0.0, W, H}, kCellOccupied);
    const std::string prefix = "f" + std::to_string(f) + "_";
    int n_room = 0, n_ward = 0, n_corr = 0;
    std::vector<Space> spaces;
    const auto add = [&](Rect r, const std::string& kind, const std::string& name) {
      spaces.push_back({r, kind, name});
      fb.CarveInterior(r);
      return r;
    };
    const auto door_span = [&](double lo, double hi) {
      const double dw = snap(o.door_width_m);
      const double a = lo + hw + 0.2, z = hi - hw - 0.2 - dw;
      const double s0 = z > a ? snap(rng.Uniform(a, z)) : snap((lo + hi - dw) / 2.0);
      return std::pair<double, double>(s0, s0 + dw);
    };

    // Lobby and the rooms beside it (doors onto the lobby). The elevator is the first room north.
    const Rect lobby = add({0.0, ly0, lobby_w, ly1}, "lobby", prefix + "lobby");
    for (const bool north : {true, false}) {
      const double y0 = north ? ly1 : 0.0, y1 = north ? H : ly0;
      if (y1 - y0 < 1e-9) continue;
      double x = 0.0;
      bool first = true;
      while (x < lobby_w - 1e-9) {
        double wdt = snap(rng.Uniform(4.0, 6.5));
        const bool elevator = north && first && o.floors > 1;
        if (elevator) wdt = 3.0;
        if (lobby_w - (x + wdt) < 3.0) wdt = lobby_w - x;
        const std::string kind = elevator ? "elevator" : "room";
        const std::string name = elevator ? prefix + "elevator" : prefix + "room" + std::to_string(n_room++);
        const Rect r = add({x, y0, x + wdt, y1}, kind, name);
        if (elevator) b.elevator_zone.push_back(-1);  // fixed up below with the zone index
        const auto [s0, s1] = door_span(r.x0, r.x1);
        fb.OpenHorizontal(north ? y0 : y1, s0, s1);
        x += wdt;
        first = false;
      }
    }

    // Main corridor segments, cut between branches; the lobby opens onto the first one.
    {
      std::vector<double> cuts = {lobby_w};
      for (double c : main_cuts) cuts.push_back(c);
      cuts.push_back(W);
      for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
        add({cuts[i], ym0, cuts[i + 1], ym1}, "corridor", prefix + "corridor" + std::to_string(n_corr++));
        fb.OpenVertical(cuts[i], ym0 + hw, ym1 - hw);
      }
    }
    // Branch corridors north and south of the main corridor, in segments, open end to end.
    for (const Rect& br : branches) {
      for (const bool north : {true, false}) {
        const double y0 = north ? ym1 : 0.0, y1 = north ? H : ym0;
        const int n = std::max(1, static_cast<int>(std::ceil((y1 - y0) / o.max_corridor_segment_m)));
        double prev = north ? y0 : y1;
        for (int k = 1; k <= n; ++k) {
          const double next = north ? (k == n ? y1 : snap(y0 + (y1 - y0) * k / n))
                                    : (k == n ? y0 : snap(y1 - (y1 - y0) * k / n));
          const Rect r = north ? Rect{br.x0, prev, br.x1, next} : Rect{br.x0, next, br.x1, prev};
          add(r, "corridor", prefix + "corridor" + std::to_string(n_corr++));
          fb.OpenHorizontal(prev, br.x0 + hw, br.x1 - hw);
          prev = next;
        }
      }
    }
    // Room columns: patient rooms (3.6-5.5 m) or wards (8-12 m), door onto the branch.
    for (const Column& col : columns) {
      for (const bool north : {true, false}) {
        const double y0 = north ? ym1 : 0.0, y1 = north ? H : ym0;
        const bool ward = rng.Bernoulli(o.ward_probability);
        const double lo = ward ? 8.0 : 3.6, hi = ward ? 12.0 : 5.5;
        double y = y0;
        while (y < y1 - 1e-9) {
          double h = snap(rng.Uniform(lo, hi));
          if (y1 - (y + h) < lo) h = y1 - y;
          const std::string kind = ward ? "ward" : "room";
          const std::string name =
              prefix + (ward ? "ward" + std::to_string(n_ward++) : "room" + std::to_string(n_room++));
          const Rect r = add({col.x0, y, col.x1, y + h}, kind, name);
          const auto [s0, s1] = door_span(r.y0, r.y1);
          const bool west = col.door == Side::kWest;
          fb.OpenVertical(west ? r.x0 : r.x1, s0, s1);
          // Furniture against the wall opposite the door.
          const double far = west ? r.x1 - hw : r.x0 + hw;
          const double depth = r.x1 - r.x0;
          const auto bed = [&](double yb) {
            const double len = 2.0;
            fb.Furniture(west ? Rect{far - len, yb, far, yb + 0.9} : Rect{far, yb, far + len, yb + 0.9});
          };
          if (ward) {
            for (double yb = snap(r.y0 + hw + 0.8); yb + 0.9 <= r.y1 - hw - 0.8; yb += 2.4) bed(yb);
          } else if (depth >= 4.5 && h >= 3.0) {
            const double ymid = snap((r.y0 + r.y1) / 2.0 - 0.45);
            bed(ymid);
            if (h / 2.0 >= 1.3) {
              const double cy1 = r.y1 - hw;
              fb.Furniture(west ? Rect{far - 0.5, cy1 - 0.6, far, cy1} : Rect{far, cy1 - 0.6, far + 0.5, cy1});
            }
          }
          y += h;
        }
      }
    }
    // Lobby furniture: pillars on a 6 m grid clear of the corridor line, and a reception desk.
    for (double px = 3.0; px + 0.5 <= lobby.x1 - 2.5; px += 6.0) {
      for (double py = lobby.y0 + 2.5; py + 0.5 <= lobby.y1 - 2.5; py += 6.0) {
        if (std::abs(py - (ym0 + ym1) / 2.0) < cw) continue;
        fb.Furniture({snap(px), snap(py), snap(px) + 0.5, snap(py) + 0.5});
      }
    }
    if (lobby.y1 - lobby.y0 >= 8.0 && lobby.x1 >= 8.0) {
      const double dx = snap(lobby.x1 / 2.0 - 1.5), dy = snap(lobby.y1 - hw - 3.0);
      fb.Furniture({dx, dy, dx + 3.0, dy + 0.8});
    }

    for (const Space& s : spaces) {
      ZoneDef z;
      z.name = s.name;
      z.kind = s.kind;
      z.floor = f;
      z.polygon = {{s.r.x0, s.r.y0}, {s.r.x1, s.r.y0}, {s.r.x1, s.r.y1}, {s.r.x0, s.r.y1}};
      if (s.kind == "elevator") b.elevator_zone.back() = static_cast<int>(b.zones.size());
      if (f == 0 && s.kind == "lobby") b.start_zone = static_cast<int>(b.zones.size());
      b.zones.push_back(std::move(z));
    }
    b.floors.push_back(std::move(floor));
  }
  FinishZones(&b);
  return b;
}

}  // namespace zm::sim
