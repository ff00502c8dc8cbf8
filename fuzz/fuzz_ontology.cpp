// Ontology YAML (fine classes to coarse classes, colours, label ids).
#include <string_view>

#include "slamvdb/core/error.hpp"
#include "slamvdb/ontology/ontology.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const auto o = slamvdb::Ontology::parse(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.yaml");
    (void)o;
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
