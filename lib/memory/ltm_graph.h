// LtmGraph: what basic's graph searches read of a node in long-term memory (LTM), and from where.
//
// RTAB-Map's Memory::getNeighborsId expands working-memory nodes from RAM, but reads each
// long-term-memory node it admits from the database: getWeight, then loadLinks, two point
// queries (basic-baseline.md §3.1). BasicPolicy reads LTM nodes only through this interface, so
// its decisions use data that came from wherever the implementation reads it, while the policy
// itself knows nothing of SQL (docs/design.md: "policies know nothing of SQL"). It is the
// Cartographer shape (docs/style.md): the policy decides over a small role interface.
//
//   SourceLtmGraph  the run-time's: KeyframeSource::ReadGraphNodes, i.e. MapDb executes the two
//                   statements per node (each its own autocommit transaction) and the policy
//                   decides on what they returned; in tests the fake source plays the database.
//   IndexLtmGraph   the MapIndex (RAM) standing in for the database, for the decision-only
//                   benchmark and tests that have no source: it executes nothing and counts what
//                   the database would have been asked (2 statements, 2 transactions a node).
//
// Both answer the same on the same map (tests/memory/basic_policy_test.cc compares the policy's
// decisions over a real MapDb with its decisions over the MapIndex). Neither allocates once
// constructed: a node's edges land in a buffer reserved for the map's largest degree.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "common/status.h"
#include "mapdb/map_db.h"
#include "memory/map_index.h"

namespace zm {

// One LTM node as read: its weight and its links (both directions, one edge per (to, type),
// links to keyframes the map does not know dropped, as MapIndex drops them).
struct LtmNode {
  std::int32_t weight = 0;
  std::span<const GraphEdge> edges;  // valid until the next Read on the same LtmGraph
};

class LtmGraph {
 public:
  virtual ~LtmGraph() = default;
  // Reads keyframe k's weight and links and adds what that cost to *stats. On an error *node is
  // unspecified; the caller goes on without the node.
  [[nodiscard]] virtual Status Read(KfIndex k, LtmNode* node, LoadStats* stats) = 0;
};

// Reads through KeyframeSource::ReadGraphNodes, one node per call (RTAB-Map reads them one at a
// time, as its search reaches them). `index` and `source` must outlive it.
class SourceLtmGraph final : public LtmGraph, private GraphNodeSink {
 public:
  SourceLtmGraph(const MapIndex& index, KeyframeSource& source);
  [[nodiscard]] Status Read(KfIndex k, LtmNode* node, LoadStats* stats) override;

 private:
  void Node(KeyframeId id, std::int32_t weight) override;
  void Link(const LinkRecord& link) override;

  const MapIndex& index_;
  KeyframeSource& source_;
  KeyframeId reading_{0};
  bool got_node_ = false;
  bool overflow_ = false;
  std::int32_t weight_ = 0;
  std::vector<GraphEdge> edges_;  // capacity: the largest degree in the index
};

// The MapIndex standing in for the database (see above): no I/O, the would-be cost counted.
class IndexLtmGraph final : public LtmGraph {
 public:
  explicit IndexLtmGraph(const MapIndex& index) : index_(index) {}
  [[nodiscard]] Status Read(KfIndex k, LtmNode* node, LoadStats* stats) override;

 private:
  const MapIndex& index_;
};

}  // namespace zm
