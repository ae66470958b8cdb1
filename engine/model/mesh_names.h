// Nodes and elements as the user knows them: an imported mesh's own numbers (Gmsh's node and
// element tags, a deck's ids; Scene::node_tags, FemReference::element_tags), which springfit
// renumbers from 0. Messages name them so that the user can find them in their mesh tool.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "engine/model/scene.h"

namespace springfit {

// "node 88 (the mesh's tags)", "nodes 88, 93 (the mesh's tags)"; by springfit's 0-based
// indices when the scene has no tags: "nodes 3, 4".
std::string NodesNamed(const Scene& scene, const std::vector<int>& nodes);

// "the mesh's element 1207" when the scene has element tags, else "" (the index alone is in
// the caller's path or text).
std::string MeshElementTag(const Scene& scene, std::size_t element);

// "element 31 (the mesh's element 1207)", or "element 31" without tags.
std::string ElementNamed(const Scene& scene, std::size_t element);

}  // namespace springfit
