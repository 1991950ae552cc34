#include "terrain/surface_contract.h"

namespace terrain {

std::string node_name(const NodeKey& k) {
  return std::to_string(k.level) + "/" + std::to_string(k.x) + "/" + std::to_string(k.y);
}

}  // namespace terrain
