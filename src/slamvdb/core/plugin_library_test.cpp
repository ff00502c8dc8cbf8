#include "slamvdb/core/plugin_library.hpp"

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

}  // namespace
}  // namespace slamvdb
