#pragma once
// A map's submaps as alignment reads them (place_descriptors.hpp: SessionSubmap): each one's
// anchor and the centres of its occupied voxels in its own frame, nothing else (no scans).
#include <vector>

#include "slamvdb/sessions/place_descriptors.hpp"

namespace slamvdb {
class SemanticMap;
}

namespace slamvdb::sessions {

// Every submap of `map` (finished and active), by id; each submap's voxels sorted by key, so
// that the alignment of two maps does not depend on hash-table order.
std::vector<SessionSubmap> session_submaps(const SemanticMap& map);

}  // namespace slamvdb::sessions
