#pragma once
// The fleet schema's migrations (internal to the fleet part): step i takes a database from
// version i to i + 1; step 0 creates the schema in an empty database. A new version appends a
// step and never edits an old one, so every database reaches the same tables by the same SQL.
#include <span>

namespace slamvdb::fleet {

std::span<const char* const> fleet_migrations();

}  // namespace slamvdb::fleet
