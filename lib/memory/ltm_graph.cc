// LtmGraph implementations: the database through the KeyframeSource, or the MapIndex.
#include "memory/ltm_graph.h"

#include <algorithm>
#include <string>

namespace zm {

SourceLtmGraph::SourceLtmGraph(const MapIndex& index, KeyframeSource& source)
    : index_(index), source_(source) {
  std::size_t degree = 0;
  for (KfIndex k = 0; k < index.keyframe_count(); ++k) {
    degree = std::max(degree, index.Edges(k).size());
  }
  edges_.reserve(degree);
}

void SourceLtmGraph::Node(KeyframeId id, std::int32_t weight) {
  if (id != reading_) return;
  got_node_ = true;
  weight_ = weight;
}

void SourceLtmGraph::Link(const LinkRecord& link) {
  const KeyframeId other = link.from == reading_ ? link.to : link.from;
  const KfIndex to = index_.Find(other);
  if (to == kNoKf || other == reading_) return;  // as MapIndex::Build drops them
  const GraphEdge e{to, link.type};
  for (const GraphEdge& have : edges_) {
    if (have.to == e.to && have.type == e.type) return;  // one edge per (to, type)
  }
  if (edges_.size() == edges_.capacity()) {  // never grow: the map changed under the run
    overflow_ = true;
    return;
  }
  edges_.push_back(e);
}

Status SourceLtmGraph::Read(KfIndex k, LtmNode* node, LoadStats* stats) {
  reading_ = index_.id(k);
  got_node_ = false;
  overflow_ = false;
  edges_.clear();
  const KeyframeId ids[] = {reading_};
  Result<LoadStats> read = source_.ReadGraphNodes(ids, this);
  if (!read.ok()) return read.status();
  *stats += *read;
  if (!got_node_) {
    return NotFound("the map database returned no weight for keyframe " +
                    std::to_string(reading_.value));
  }
  if (overflow_) {
    return Corrupt("keyframe " + std::to_string(reading_.value) +
                   " has more links in the map database than when the run started (" +
                   std::to_string(edges_.capacity()) + " at most): the map changed under the run");
  }
  node->weight = weight_;
  node->edges = edges_;
  return Status::Ok();
}

Status IndexLtmGraph::Read(KfIndex k, LtmNode* node, LoadStats* stats) {
  node->weight = index_.weight(k);
  node->edges = index_.Edges(k);
  stats->queries += 2;  // what SourceLtmGraph would execute: the weight, the links
  stats->transactions += 2;
  return Status::Ok();
}

}  // namespace zm
