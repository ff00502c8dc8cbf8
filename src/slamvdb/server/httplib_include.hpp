#pragma once
// cpp-httplib (Debian's libcpp-httplib-dev) without what its system headers leak: <resolv.h>
// defines the macro `_res`, which Eigen uses as a parameter name, so any Eigen header included
// after httplib.h (in this file or, in a unity build, in the next file) would fail to compile.
#include <httplib.h>
#ifdef _res
#undef _res
#endif
