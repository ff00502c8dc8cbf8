#pragma once
// A session: one drive of one robot, the unit a multi-session map (issue 23) is made of. Every
// submap belongs to one session (SubmapInfo::session); a map's sessions are listed in
// MapInfo::sessions. A map that lists none is one implicit session, id 0 (what every map made
// before sessions were recorded is).
#include <string>

#include "slamvdb/map/submap.hpp"

namespace slamvdb {

struct SessionInfo {
  int id = 0;
  std::string name{};    // a short name for the user (a map file's stem when nothing else is known)
  std::string source{};  // what the session was built from (dataset path; SIMULATED or not)
  std::string robot{};   // which robot drove it, when known
  TimeRange time{};      // the union of its submaps' time ranges
};

}  // namespace slamvdb
