#include "slamvdb/core/plugin_library.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

// A plugin that is not there is an Error naming what it is for, the file and where it was looked
// for (the executable's folder first), never a crash or a null address.
TEST(PluginLibrary, AMissingPluginIsAnErrorNamingWhereItLooked) {
  try {
    plugin_symbol("libslamvdb_no_such_plugin.so", "entry", "the test's plugin");
    FAIL() << "no error";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("the test's plugin: libslamvdb_no_such_plugin.so was not found"), std::string::npos)
        << message;
    EXPECT_NE(message.find("lib/slamvdb/libslamvdb_no_such_plugin.so"), std::string::npos) << message;
  }
}

#ifdef SLAMVDB_WITH_TORCH
// The TorchScript backend is built beside the test executable, and its entry point is found; a
// symbol it does not export is an Error naming the library.
TEST(PluginLibrary, TheTorchScriptBackendIsFoundAndAMissingSymbolIsAnError) {
  EXPECT_NE(plugin_symbol("libslamvdb_torch_inference.so", "slamvdb_torch_encoder_factories", "backend"), nullptr);
  try {
    plugin_symbol("libslamvdb_torch_inference.so", "slamvdb_no_such_symbol", "backend");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("has no slamvdb_no_such_symbol"), std::string::npos) << e.what();
  }
}
#endif

// The image codecs' plugin (every build has it) is found and its table has this build's version; a
// table of another version is an Error naming the file and both versions, before any call.
struct TestTable {
  int version = 0;
};
TEST(PluginLibrary, TheImageCodecsAreFoundAndAnotherVersionIsRefused) {
  void* entry = plugin_symbol("libslamvdb_image_codecs.so", "slamvdb_image_codecs", "codecs");
  ASSERT_NE(entry, nullptr);
  const int version = reinterpret_cast<const TestTable* (*)()>(entry)()->version;
  EXPECT_GE(version, 1);
  EXPECT_EQ(&plugin_exports<TestTable>("libslamvdb_image_codecs.so", "slamvdb_image_codecs", "codecs", version),
            reinterpret_cast<const TestTable* (*)()>(entry)());
  try {
    plugin_exports<TestTable>("libslamvdb_image_codecs.so", "slamvdb_image_codecs", "codecs", version + 1);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(fmt::format("libslamvdb_image_codecs.so is version {}, this slamvdb needs {}",
                                                     version, version + 1)),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace slamvdb
