#include "slamvdb/sensors/tf_buffer.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <deque>
#include <set>

namespace slamvdb {

namespace {

Pose pose_of_parts(const double* t, const double* q) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  T.translation() = Vec3d(t[0], t[1], t[2]);
  return T;
}

}  // namespace

double TfEdgeSummary::rate_hz() const {
  if (is_static || messages < 2 || !(last > first)) return 0.0;
  return static_cast<double>(messages - 1) / (last - first);
}

TfBuffer::Edge& TfBuffer::edge(const std::string& parent, const std::string& child, double stamp) {
  Edge& e = edges_[{parent, child}];
  if (e.messages == 0) {
    e.parent = parent;
    e.child = child;
    e.first = e.last = stamp;
  }
  ++e.messages;
  e.first = std::min(e.first, stamp);
  e.last = std::max(e.last, stamp);
  return e;
}

void TfBuffer::add_static(const std::string& parent, const std::string& child, double stamp, const Pose& T_parent_child) {
  Edge& e = edge(parent, child, stamp);
  e.has_static = true;
  e.static_pose = T_parent_child;
}

void TfBuffer::add(const std::string& parent, const std::string& child, double stamp, const Pose& T_parent_child) {
  Edge& e = edge(parent, child, stamp);
  e.dynamic = true;
  if (!keep_transforms_) return;
  Sample s{stamp, {}, {}};
  const Vec3d t = T_parent_child.translation();
  Eigen::Quaterniond q(T_parent_child.linear());
  if (!e.samples.empty() && q.dot(Eigen::Quaterniond(e.samples.back().q[0], e.samples.back().q[1],
                                                     e.samples.back().q[2], e.samples.back().q[3])) < 0)
    q.coeffs() = -q.coeffs();  // the same rotation on the side of its neighbour: equal runs compare equal
  s.t[0] = t.x(), s.t[1] = t.y(), s.t[2] = t.z();
  s.q[0] = q.w(), s.q[1] = q.x(), s.q[2] = q.y(), s.q[3] = q.z();
  const auto same = [&](const Sample& o) {
    return std::equal(s.t, s.t + 3, o.t) && std::equal(s.q, s.q + 4, o.q);
  };
  auto& v = e.samples;
  if (v.empty() || stamp > v.back().stamp) {
    // A run of equal transforms keeps its first and last stamps: the middle one moves to the end.
    if (v.size() >= 2 && same(v.back()) && same(v[v.size() - 2])) v.back().stamp = stamp;
    else v.push_back(s);
    return;
  }
  const auto at = std::lower_bound(v.begin(), v.end(), stamp, [](const Sample& a, double x) { return a.stamp < x; });
  if (at != v.end() && at->stamp == stamp) *at = s;  // a stamp given again: the latest holds
  else v.insert(at, s);
}

Pose TfBuffer::edge_at(const Edge& e, double t) const {
  const auto& v = e.samples;
  if (v.empty()) return e.static_pose;
  const auto describe = [&] {
    return fmt::format("tf has {} -> {} from {:.6f} s to {:.6f} s ({} stamps; held up to {} s beyond)", e.parent,
                       e.child, v.front().stamp, v.back().stamp, v.size(), tolerance_);
  };
  if (!std::isfinite(t)) throw TfLookupError(fmt::format("time {} is not finite; {}", t, describe()));
  if (t <= v.front().stamp) {
    if (v.front().stamp - t > tolerance_)
      throw TfLookupError(fmt::format("time {:.6f} s is before the first transform: {}", t, describe()));
    return pose_of_parts(v.front().t, v.front().q);
  }
  if (t >= v.back().stamp) {
    if (t - v.back().stamp > tolerance_)
      throw TfLookupError(fmt::format("time {:.6f} s is after the last transform: {}", t, describe()));
    return pose_of_parts(v.back().t, v.back().q);
  }
  const auto hi = std::upper_bound(v.begin(), v.end(), t, [](double x, const Sample& a) { return x < a.stamp; });
  const Sample& b = *hi;
  const Sample& a = *(hi - 1);
  if (a.stamp == t) return pose_of_parts(a.t, a.q);
  const double alpha = (t - a.stamp) / (b.stamp - a.stamp);
  const Eigen::Quaterniond qa(a.q[0], a.q[1], a.q[2], a.q[3]), qb(b.q[0], b.q[1], b.q[2], b.q[3]);
  Pose T = Pose::Identity();
  T.linear() = qa.normalized().slerp(alpha, qb.normalized()).toRotationMatrix();
  for (int i = 0; i < 3; ++i) T.translation()[i] = a.t[i] + alpha * (b.t[i] - a.t[i]);
  return T;
}

bool TfBuffer::Chain::is_static() const {
  return std::all_of(steps_.begin(), steps_.end(), [](const Step& s) { return s.edge->samples.empty(); });
}

Pose TfBuffer::Chain::at(double t) const {
  Pose T = Pose::Identity();
  for (const Step& s : steps_) {
    const Pose T_parent_child = buffer_->edge_at(*s.edge, t);
    T = T * (s.forward ? T_parent_child : T_parent_child.inverse());
  }
  return T;
}

std::optional<TfBuffer::Chain> TfBuffer::chain(const std::string& a, const std::string& b) const {
  // Breadth first from a, remembering how each frame was reached.
  std::map<std::string, std::pair<std::string, Chain::Step>> came_from;
  std::set<std::string> seen{a};
  std::deque<std::string> todo{a};
  while (!todo.empty() && !seen.count(b)) {
    const std::string x = todo.front();
    todo.pop_front();
    for (const auto& [pair, e] : edges_) {
      const bool down = e.parent == x, up = e.child == x;
      const std::string& next = down ? e.child : e.parent;
      if ((!down && !up) || seen.count(next)) continue;
      seen.insert(next);
      came_from.emplace(next, std::make_pair(x, Chain::Step{&e, down}));
      todo.push_back(next);
    }
  }
  if (!seen.count(b)) return std::nullopt;
  Chain c;
  c.buffer_ = this;
  for (std::string x = b; x != a;) {
    const auto& [previous, step] = came_from.at(x);
    c.steps_.push_back(step);
    x = previous;
  }
  std::reverse(c.steps_.begin(), c.steps_.end());
  return c;
}

Pose TfBuffer::lookup(const std::string& a, const std::string& b, double t) const {
  const auto c = chain(a, b);
  if (!c) {
    const auto known = frames();
    throw TfLookupError(fmt::format("tf does not connect frames '{}' and '{}' (frames seen: {})", a, b,
                                    known.empty() ? "none" : fmt::format("{}", fmt::join(known, ", "))));
  }
  try {
    return c->at(t);
  } catch (const TfLookupError& e) {
    throw TfLookupError(fmt::format("no transform {} -> {} at {:.6f} s: {}", a, b, t, e.what()));
  }
}

std::vector<std::string> TfBuffer::frames() const {
  std::set<std::string> all;
  for (const auto& [pair, e] : edges_) all.insert(pair.first), all.insert(pair.second);
  return {all.begin(), all.end()};
}

std::vector<TfEdgeSummary> TfBuffer::edges() const {
  std::vector<TfEdgeSummary> out;
  for (const auto& [pair, e] : edges_)
    out.push_back({e.parent, e.child, !e.dynamic, e.messages, e.first, e.last});
  return out;
}

std::size_t TfBuffer::stored_stamps() const {
  std::size_t n = 0;
  for (const auto& [pair, e] : edges_) n += e.samples.size();
  return n;
}

}  // namespace slamvdb
