#pragma once
// Every entry point body, for the ISA units (dispatch/isa_unit.cpp) only.
// A host that builds for one ISA may include this and call `Entry<Arch>`
// directly instead of linking the ISA units.

#include "../cells/queries_impl.hpp"
#include "../mesh/cell_boxes_impl.hpp"
#include "../traverse/queries_impl.hpp"
#include "../traverse/occlusion_query_impl.hpp"
#include "../render/render_impl.hpp"
