#include "engine/api/scene.h"

namespace springfit {

std::string NodesNamed(const Scene& scene, const std::vector<int>& nodes) {
  std::string text;
  for (int node : nodes) {
    text += text.empty() ? "" : ", ";
    const bool tagged = static_cast<std::size_t>(node) < scene.node_tags.size();
    text += std::to_string(tagged ? scene.node_tags[static_cast<std::size_t>(node)] : node);
  }
  const bool tagged = !scene.node_tags.empty();
  return (nodes.size() == 1 ? "node " : "nodes ") + text + (tagged ? " (the mesh's tags)" : "");
}

std::string MeshElementTag(const Scene& scene, std::size_t element) {
  const std::vector<long long>& tags = scene.reference.fem.element_tags;
  return element < tags.size() ? "the mesh's element " + std::to_string(tags[element]) : "";
}

std::string ElementNamed(const Scene& scene, std::size_t element) {
  const std::string tag = MeshElementTag(scene, element);
  return "element " + std::to_string(element) + (tag.empty() ? "" : " (" + tag + ")");
}

}  // namespace springfit
