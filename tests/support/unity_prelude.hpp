#pragma once
// Included first in every unity TU of the test stages (tests/CMakeLists.txt).
// Some library headers name `detail::` from namespace cellray, which becomes
// ambiguous once a kernel header has declared cellray::CELLRAY_ISA_NS::detail
// (e.g. mesh/validate.hpp after cells/hex.hpp). One test file includes them
// in a working order, but in a unity TU another file's includes may come
// first; parsing the public surface first restores the order every single
// file compiles in. (Reported to the lead: a library include-order bug.)

#include <cellray/cellray.hpp>
#include <cellray/io/read_mesh.hpp>
