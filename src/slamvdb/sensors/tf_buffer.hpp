#pragma once
// A transform buffer in time, as /tf_static and /tf give it: every stamped transform of each
// parent-child pair, and the transform between two frames through the tree at a time, each edge
// interpolated between its two neighbouring stamps (translation linear, rotation slerp).
//
// Edges: a pair seen only on /tf_static is static (its latest transform holds at every time); a
// pair seen on /tf is dynamic. Outside a dynamic edge's recorded stamps a lookup holds the nearest
// transform up to `tolerance` seconds (default kDefaultTfTolerance; nothing is extrapolated) and
// is an error beyond it, naming the frames, the time and the recorded range.
// Memory: 64 bytes per stored stamp of a dynamic edge (stamp, translation, quaternion as doubles);
// a run of equal transforms (a fixed joint republished on /tf) keeps only its first and last
// stamps, so memory follows the number of changes, not of messages (a 100 Hz moving joint: 23 MB
// per hour). The counts, spans and static / dynamic kinds of every edge are kept for `inspect`.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/types.hpp"

namespace slamvdb {

// How far outside a dynamic edge's recorded stamps the nearest transform is held (seconds).
inline constexpr double kDefaultTfTolerance = 0.05;

// A lookup that cannot be answered: frames not connected, or a time outside a dynamic edge's range.
class TfLookupError : public Error {
 public:
  using Error::Error;
};

// One parent-child pair as `inspect` shows it.
struct TfEdgeSummary {
  std::string parent, child;
  bool is_static = true;
  std::uint64_t messages = 0;        // transforms received for the pair
  double first = 0.0, last = 0.0;    // their stamps (seconds)
  double rate_hz() const;            // over the span (0 with fewer than two, or static)
};

class TfBuffer {
  struct Edge;

 public:
  // keep_transforms false: only the edges' counts and spans are kept (`inspect`), not for lookups.
  explicit TfBuffer(double tolerance = kDefaultTfTolerance, bool keep_transforms = true)
      : tolerance_(tolerance), keep_transforms_(keep_transforms) {}

  // T_parent_child from /tf_static: holds at every time (a later one for the pair replaces it).
  void add_static(const std::string& parent, const std::string& child, double stamp, const Pose& T_parent_child);
  // T_parent_child at `stamp` from /tf. Stamps may come in any order.
  void add(const std::string& parent, const std::string& child, double stamp, const Pose& T_parent_child);

  // The path between two frames, found once and evaluated at many times.
  class Chain {
   public:
    bool is_static() const;
    // T_a_b at time t. Throws TfLookupError outside a dynamic edge's range (beyond the tolerance).
    Pose at(double t) const;

   private:
    friend class TfBuffer;
    struct Step {
      const Edge* edge;
      bool forward;  // parent -> child along the path (else the inverse)
    };
    std::vector<Step> steps_;
    const TfBuffer* buffer_ = nullptr;
  };
  // The chain from a to b (T_a_b), or nullopt when tf does not connect them. The chain refers to
  // this buffer: it must not outlive it, and edges added later are not in it.
  std::optional<Chain> chain(const std::string& a, const std::string& b) const;
  // T_a_b at time t. Throws TfLookupError naming the frames when they are not connected.
  Pose lookup(const std::string& a, const std::string& b, double t) const;

  bool empty() const { return edges_.empty(); }
  std::vector<std::string> frames() const;  // every frame seen, sorted
  std::vector<TfEdgeSummary> edges() const;  // by parent, then child
  std::size_t stored_stamps() const;        // of all dynamic edges (what memory follows)
  double tolerance() const { return tolerance_; }

 private:
  struct Sample {
    double stamp;
    double t[3];
    double q[4];  // w x y z
  };
  struct Edge {
    std::string parent, child;
    bool has_static = false, dynamic = false;
    Pose static_pose = Pose::Identity();
    std::vector<Sample> samples;  // sorted by stamp (dynamic edges)
    std::uint64_t messages = 0;
    double first = 0.0, last = 0.0;
  };
  Edge& edge(const std::string& parent, const std::string& child, double stamp);
  Pose edge_at(const Edge& e, double t) const;

  std::map<std::pair<std::string, std::string>, Edge> edges_;
  double tolerance_;
  bool keep_transforms_;
};

}  // namespace slamvdb
