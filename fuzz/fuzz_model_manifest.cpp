// Model manifests (JSON), and the resize plan they imply for an image.
#include "slamvdb/core/error.hpp"
#include "slamvdb/inference/model_manifest.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const slamvdb::ModelManifest m = slamvdb::parse_model_manifest(
        std::string_view(reinterpret_cast<const char*>(data), size), "/fuzz/model.json");
    if (m.kind != slamvdb::ModelKind::kText) {
      const auto plan = slamvdb::plan_resize({1920, 1200}, m.input, "fuzz");
      if (plan.crop.x < 0 || plan.crop.y < 0 || plan.crop.br().x > plan.scaled.width ||
          plan.crop.br().y > plan.scaled.height)
        __builtin_trap();  // the crop stays inside the scaled image
    }
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
