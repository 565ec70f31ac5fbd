#pragma once
// The public surface in one include: mesh views and validation, the min-max
// BVH (build, refit, statistics), queries (first hits, samples) and the
// renderer. Needs xsimd, oneTBB and GLM only. The file readers and image
// writers are separate (cellray/io/*.hpp: pugixml, zlib).

#include "bvh/build.hpp"
#include "bvh/refit.hpp"
#include "bvh/refit_plan.hpp"
#include "bvh/stats.hpp"
#include "mesh/cell_mesh.hpp"
#include "mesh/generate.hpp"
#include "mesh/validate.hpp"
#include "render/render.hpp"
#include "traverse/occlusion_query.hpp"
#include "traverse/queries.hpp"
