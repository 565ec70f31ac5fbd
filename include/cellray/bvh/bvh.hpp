#pragma once
// The min-max BVH stage in one include: node layout, builders, refit, stats.

#include "build.hpp"
#include "node.hpp"
#include "refit.hpp"
#include "refit_plan.hpp"
#include "stats.hpp"
