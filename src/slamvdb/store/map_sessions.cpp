// The sessions of a map file (format version 4): the `sessions` table and which session each
// submap belongs to (`submap_sessions`), written and read with every value checked; files of
// versions 1-3 read as one session named after the file.
#include <fmt/format.h>

#include <cmath>
#include <map>
#include <set>

#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/store/map_rows.hpp"

namespace slamvdb::store {
namespace {

int64_t session_crc(int64_t id, const std::string& name, const std::string& source, const std::string& robot,
                    const TimeRange& time) {
  return Crc()
      .add(id)
      .add(name.data(), name.size() + 1)  // with the terminator: ("ab", "c") differs from ("a", "bc")
      .add(source.data(), source.size() + 1)
      .add(robot.data(), robot.size() + 1)
      .add_real(time.empty() ? 0.0 : time.begin)
      .add_real(time.empty() ? 0.0 : time.end)
      .value();
}

int64_t submap_session_crc(int64_t submap, int64_t session) { return Crc().add(submap).add(session).value(); }

}  // namespace

std::vector<SessionInfo> sessions_to_write(const MapInfo& info, const std::vector<SubmapSummary>& submaps,
                                           const std::string& implicit_name) {
  std::vector<SessionInfo> sessions = info.sessions;
  if (sessions.empty()) sessions.push_back({0, implicit_name, info.source, "", {}});
  std::map<int, SessionInfo*> by_id;
  for (SessionInfo& s : sessions) {
    if (s.name.empty()) throw Error(fmt::format("session {} has no name", s.id));
    if (!by_id.emplace(s.id, &s).second) throw Error(fmt::format("session id {} is listed twice", s.id));
  }
  // From its submaps, so that it stays true after crops and merges; a session left with none (its
  // submaps merged into another session's) keeps the range it had: which drive is newer (a
  // voxel's last-observed session) depends on it.
  std::map<int, TimeRange> of_submaps;
  for (const SubmapSummary& submap : submaps) {
    if (!by_id.contains(submap.info.session))
      throw Error(fmt::format("submap {} belongs to session {}, which the map does not list", submap.info.id,
                              submap.info.session));
    of_submaps[submap.info.session].extend(submap.info.time_range);
  }
  for (auto& [id, time] : of_submaps) by_id.at(id)->time = time;
  return sessions;
}

void write_session_rows(Database& db, const std::vector<SessionInfo>& sessions) {
  db.exec("DELETE FROM sessions");
  Statement insert(db, "INSERT INTO sessions(id, name, source, robot, time_begin, time_end, crc) VALUES(?, ?, ?, ?, ?, ?, ?)");
  for (const SessionInfo& s : sessions) {
    insert.bind(1, int64_t{s.id}).bind(2, s.name).bind(3, s.source).bind(4, s.robot);
    if (s.time.empty()) insert.bind_null(5).bind_null(6);
    else insert.bind_real(5, s.time.begin).bind_real(6, s.time.end);
    insert.bind(7, session_crc(s.id, s.name, s.source, s.robot, s.time)).insert();
  }
}

void write_submap_session_row(Database& db, const SubmapInfo& info) {
  Statement insert(db, "INSERT OR REPLACE INTO submap_sessions(submap, session, crc) VALUES(?, ?, ?)");
  insert.bind(1, int64_t{info.id}).bind(2, int64_t{info.session}).bind(3, submap_session_crc(info.id, info.session)).insert();
}

void read_submap_session_rows(Database& db, std::vector<SubmapSummary>& submaps) {
  std::map<int64_t, int64_t> session_of;
  Statement rows(db, "SELECT submap, session, crc FROM submap_sessions ORDER BY submap, session");
  while (rows.step()) {
    const int64_t submap = rows.int64(0), session = rows.int64(1);
    if (submap_session_crc(submap, session) != rows.int64(2))
      throw Error(fmt::format("CRC mismatch in the session row of submap {}: the file is corrupt", submap));
    if (!session_of.emplace(submap, session).second)
      throw Error(fmt::format("submap {} belongs to several sessions (table submap_sessions); this slamvdb reads "
                              "one session per submap",
                              submap));
  }
  for (SubmapSummary& s : submaps) {
    const auto it = session_of.find(s.info.id);
    if (it == session_of.end())
      throw Error(fmt::format("submap {} has no session (no row in table submap_sessions)", s.info.id));
    if (it->second != static_cast<int>(it->second))
      throw Error(fmt::format("submap {} names session {}, out of range", s.info.id, it->second));
    s.info.session = static_cast<int>(it->second);
    session_of.erase(it);
  }
  if (!session_of.empty())
    throw Error(fmt::format("a row of table submap_sessions refers to submap {}, which is not in the file",
                            session_of.begin()->first));
}

std::vector<SessionInfo> read_session_rows(Database& db, int format_version, const std::vector<SubmapSummary>& submaps,
                                           const std::string& implicit_name, const std::string& source) {
  std::vector<SessionInfo> sessions;
  if (format_version < 4) {  // one session, as sessions_to_write makes it for a map that lists none
    SessionInfo s{0, implicit_name, source, "", {}};
    for (const SubmapSummary& submap : submaps) s.time.extend(submap.info.time_range);
    sessions.push_back(std::move(s));
    return sessions;
  }
  Statement rows(db, "SELECT id, name, source, robot, time_begin, time_end, crc FROM sessions ORDER BY id");
  while (rows.step()) {
    const int64_t id = rows.int64(0);
    SessionInfo s{static_cast<int>(id), rows.text(1), rows.text(2), rows.text(3), {}};
    if (rows.is_null(4) != rows.is_null(5))
      throw Error(fmt::format("session {} has half a time range", id));
    if (!rows.is_null(4)) s.time = {rows.real(4), rows.real(5)};
    if (id != s.id || session_crc(id, s.name, s.source, s.robot, s.time) != rows.int64(6))
      throw Error(fmt::format("CRC mismatch in the row of session {}: the file is corrupt", id));
    if (s.name.empty()) throw Error(fmt::format("session {} has no name", id));
    if (!rows.is_null(4) && !(std::isfinite(s.time.begin) && std::isfinite(s.time.end) && s.time.begin <= s.time.end))
      throw Error(fmt::format("session {} ('{}') has an impossible time range", id, escape_control(s.name)));
    sessions.push_back(std::move(s));
  }
  std::set<int> ids;
  for (const SessionInfo& s : sessions) ids.insert(s.id);
  for (const SubmapSummary& submap : submaps)
    if (ids.count(submap.info.session) == 0)
      throw Error(fmt::format("submap {} belongs to session {}, which is not in table sessions", submap.info.id,
                              submap.info.session));
  return sessions;
}

}  // namespace slamvdb::store
