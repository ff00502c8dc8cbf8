#pragma once
// The RELLIS-3D fine classes and the paper's coarse terrain ontology (section 6.2.5).
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace slamvdb {

struct FineClass {
  uint16_t id;
  std::string_view name;
  std::array<uint8_t, 3> rgb;
  int coarse;  // index into kCoarseClasses
};

// Coarse classes in the paper's order; kVoidCoarse is last and never reported (void -> second-best).
inline constexpr std::array<std::string_view, 6> kCoarseClasses = {"smooth", "rough", "bumpy", "obstacle",
                                                                   "active", "void"};
inline constexpr int kVoidCoarse = 5;

// All RELLIS-3D classes. `puddle` (31) is not placed by the paper; we put it in `bumpy` with mud,
// since a puddle on a trail is traversable with care, like mud (documented in README).
const std::vector<FineClass>& rellis_classes();
const FineClass* find_fine_class(uint16_t id);                  // nullptr if unknown
std::optional<uint16_t> find_fine_class(std::string_view name); // by name
int coarse_of(uint16_t fine_id);                                // kVoidCoarse for unknown ids

}  // namespace slamvdb
