// The engine's public surface (engine/api/): a scene prepared for identification, the one
// place its rules are checked, and the cost of one topology against its reference.
#pragma once

#include "engine/problem/cost.h"
#include "engine/problem/problem.h"
#include "engine/problem/scene_validation.h"
#include "engine/problem/small_strain.h"
