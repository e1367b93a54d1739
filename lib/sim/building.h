// A simulated building: one occupancy grid per floor plus its ground-truth zones (one per room or
// corridor segment), generated (GenerateHospital) or imported from a real floor plan
// (ImportFloorplan). Everything downstream (landmarks, routes, observations) reads only this.
//
// Invariants: floors share one grid geometry (cols, rows, resolution, origin); zone polygons are
// simple rings in map-frame metres; zone names are unique; zones of one floor together cover
// every free cell of that floor that the robot can reach (for the hospital, zone rectangles
// partition the building exactly; for floor plans every reachable free cell has a label).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "common/status.h"
#include "sim/grid.h"

namespace zm::sim {

struct ZoneDef {
  std::string name;  // unique, e.g. "f0_room12"
  std::string kind;  // room, ward, corridor, lobby, elevator
  int floor = 0;
  std::vector<Eigen::Vector2d> polygon;  // outer ring, metres
  Eigen::Vector2d viewpoint{0.0, 0.0};   // free point of largest clearance (set by FinishZones)
  double clearance_m = 0.0;              // wall distance at the viewpoint
};

struct FloorMap {
  SimGrid grid;
  std::vector<std::uint8_t> furniture;  // 1 where an occupied cell is furniture (not a wall)
  double z_m = 0.0;                     // floor level in the map frame
};

struct Building {
  std::string kind;  // "hospital" or "floorplan"
  std::vector<FloorMap> floors;
  std::vector<ZoneDef> zones;
  double wall_height_m = 2.6;
  double furniture_height_m = 0.9;
  double floor_height_m = 4.0;
  double area_m2 = 0.0;  // footprint of one floor (hospital) or free area (floor plan)
  int start_zone = 0;    // the mapping and the patrol start at this zone's viewpoint
  // Multi-floor buildings: the elevator zone of each floor (same xy on every floor); empty else.
  std::vector<int> elevator_zone;
};

struct HospitalOptions {
  std::uint64_t seed = 1;
  double area_m2 = 3000.0;     // footprint of one floor
  int floors = 1;
  double resolution_m = 0.05;  // grid cell
  double corridor_width_m = 2.4;
  double branch_width_m = 2.0;
  double door_width_m = 1.2;
  double wall_thickness_m = 0.2;
  double ward_probability = 0.3;
  double max_corridor_segment_m = 15.0;
};

// Generates a hospital-like building (see docs/sim.md: lobby, corridor spine, branches, patient
// rooms and wards with doors, furniture). Errors name the option and its limits.
[[nodiscard]] Result<Building> GenerateHospital(const HospitalOptions& options);

struct FloorplanOptions {
  std::string map_path;      // RGBA/grey occupancy PNG: white free, black occupied, grey unknown
  std::string gt_path;       // optional: one flat colour per room, black = none
  double resolution_m = 0.05;
  double min_corridor_area_m2 = 4.0;  // free components outside every room smaller than this
                                      // join the nearest room instead of becoming a corridor
};

// Imports a real floor plan. Without a ground truth the free space is cut into zones by the
// connected components of the free space after a morphological opening (coarse but usable).
[[nodiscard]] Result<Building> ImportFloorplan(const FloorplanOptions& options);

// Fills each zone's viewpoint and clearance from the floor grids (max distance to a non-free
// cell among free cells inside the polygon). Zones without a free cell get clearance 0.
void FinishZones(Building* building);

// Point-in-polygon (even-odd) used by the simulator for zone lookups and coverage checks.
[[nodiscard]] bool InsidePolygon(const std::vector<Eigen::Vector2d>& ring, const Eigen::Vector2d& p);

// Index of the first zone on `floor` containing p, or -1.
[[nodiscard]] int ZoneAt(const Building& building, int floor, const Eigen::Vector2d& p);

}  // namespace zm::sim
