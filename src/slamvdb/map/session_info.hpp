#pragma once
// A session: one drive of one robot, the unit a multi-session map (issue 23) is made of. Every
// submap belongs to one session (SubmapInfo::session); a map's sessions are listed in
// MapInfo::sessions. A map that lists none is one implicit session, id 0 (what every map made
// before sessions were recorded is).
#include <map>
#include <string>
#include <vector>

#include "slamvdb/map/submap.hpp"

namespace slamvdb {

struct SessionInfo {
  int id = 0;
  std::string name{};    // a short name for the user (a map file's stem when nothing else is known)
  std::string source{};  // what the session was built from (dataset path; SIMULATED or not)
  std::string robot{};   // which robot drove it, when known
  TimeRange time{};      // the union of its submaps' time ranges
};

// A session's name for outputs: its SessionInfo::name, or its id as text when `sessions` does not
// list it (a map built in memory that lists none).
inline std::string session_name(const std::vector<SessionInfo>& sessions, int id) {
  for (const SessionInfo& s : sessions)
    if (s.id == id) return s.name;
  return std::to_string(id);
}

// Which of two sessions is the newer, for a voxel's "last observed" session (issue 23): the one
// whose drive ended later, then the one that began later, then the larger id; a session with a
// time range is newer than one without (unknown, or not given), and two of those compare by id.
// Default-constructed: by id alone.
class SessionOrder {
 public:
  SessionOrder() = default;
  explicit SessionOrder(const std::vector<SessionInfo>& sessions) {
    for (const SessionInfo& s : sessions)
      if (!s.time.empty()) time_[s.id] = s.time;
  }
  bool newer(int a, int b) const {  // a is newer than b
    const auto ta = time_.find(a), tb = time_.find(b);
    if (ta != time_.end() && tb != time_.end()) {
      if (ta->second.end != tb->second.end) return ta->second.end > tb->second.end;
      if (ta->second.begin != tb->second.begin) return ta->second.begin > tb->second.begin;
      return a > b;
    }
    if ((ta == time_.end()) != (tb == time_.end())) return tb != time_.end() ? false : true;
    return a > b;
  }
  int newest(int a, int b) const { return newer(b, a) ? b : a; }

 private:
  std::map<int, TimeRange> time_;
};

}  // namespace slamvdb
