// The engine's public surface (engine/api/: what proto/, io/, figures/, server/ and client/ may
// include; tests/include_graph_check.py enforces it): a scene (nodes, candidates, reference,
// load cases, search settings), the candidate rules, the units, the names of a mesh's nodes
// and elements as the user knows them, and the Eigen types.
#pragma once

#include "engine/linalg/linalg.h"
#include "engine/model/candidates.h"
#include "engine/model/mesh_names.h"
#include "engine/model/scene.h"
#include "engine/model/units.h"
