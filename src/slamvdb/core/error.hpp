#pragma once
#include <stdexcept>
#include <string>

namespace slamvdb {

// Every user-facing failure (bad input file, wrong sizes, corrupt map) is reported as an Error
// whose message says what was wrong and where; the CLI prints it and exits non-zero.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace slamvdb
