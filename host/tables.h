// The tables methods read at every shading point (HEALPix geometry, BRDF
// bound tables, wis's node centres, tsis's summed-area table, ht-frontier's
// colours). A render builds the ones its method needs before it starts
// (prepareTables in integrator.h), so that its time leaves them out, owns
// them, and passes them down: no process-wide caches.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/vec3.hpp>

namespace ht {

struct HtGeometry;
struct HtNodes;
class BrdfTable;
struct TsisTable;
struct FrontierColours;
struct MaxAvgTree;
struct Scene;
struct Material;

struct MethodTables {
  std::shared_ptr<const HtGeometry> htGeometry;               // ht*, ht-frontier, oracle: the map's order
  std::shared_ptr<const HtNodes> htNodes;                     // ht*, ht-frontier: geometry and trees packed
  std::vector<std::shared_ptr<const BrdfTable>> brdfTables;   // ht* with table bounds: per scene material
  std::shared_ptr<const std::vector<glm::vec3>> wisCenters;   // wis*: node centres up to its order
  std::shared_ptr<const TsisTable> tsis;                      // tsis
  std::shared_ptr<const FrontierColours> frontierColours;     // ht-frontier: colour bins and chroma per average-tree node
  std::shared_ptr<const MaxAvgTree> compensated;               // mis-compensated: the environment technique's tree

  // Each throws an internal ht::Error when its table was not prepared.
  const HtGeometry& geometry() const;
  const HtNodes& nodes() const;
  // The table of `material`, one of scene.materials.
  const BrdfTable& brdfTable(const Scene& scene, const Material* material) const;
  const std::vector<glm::vec3>& wis() const;
  const std::shared_ptr<const TsisTable>& tsisTable() const;
  const FrontierColours& colours() const;
  const MaxAvgTree& compensatedTree() const;
};

}  // namespace ht
