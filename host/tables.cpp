#include "tables.h"

#include "error.h"
#include "scene.h"

namespace ht {

const HtGeometry& MethodTables::geometry() const {
  if (!htGeometry) throw Error("internal: HEALPix geometry used but not prepared");
  return *htGeometry;
}

const HtNodes& MethodTables::nodes() const {
  if (!htNodes) throw Error("internal: HT node records used but not prepared");
  return *htNodes;
}

const BrdfTable& MethodTables::brdfTable(const Scene& scene, const Material* material) const {
  const size_t i = size_t(material - scene.materials.data());
  if (material < scene.materials.data() || i >= brdfTables.size() || !brdfTables[i])
    throw Error("internal: BRDF table used but not prepared for this material");
  return *brdfTables[i];
}

const std::vector<glm::vec3>& MethodTables::wis() const {
  if (!wisCenters) throw Error("internal: wis node centres used but not prepared");
  return *wisCenters;
}

const std::shared_ptr<const TsisTable>& MethodTables::tsisTable() const {
  if (!tsis) throw Error("internal: tsis table used but not prepared");
  return tsis;
}

const FrontierColours& MethodTables::colours() const {
  if (!frontierColours) throw Error("internal: ht-frontier colours used but not prepared");
  return *frontierColours;
}

const MaxAvgTree& MethodTables::compensatedTree() const {
  if (!compensated) throw Error("internal: mis-compensated's tree used but not prepared");
  return *compensated;
}

}  // namespace ht
