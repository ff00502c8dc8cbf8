#pragma once
// For tests only: the message of the slamvdb::Error that `f` throws, or "" if it throws none.
#include <functional>
#include <string>

#include "slamvdb/core/error.hpp"

namespace slamvdb::testing {

inline std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace slamvdb::testing
