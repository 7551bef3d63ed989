#include "tables.h"

namespace ht {

const HtGeometry& MethodTables::geometry() const {
  if (!htGeometry) throw Error("internal: HEALPix geometry used but not prepared");
  return *htGeometry;
}

const HtNodes& MethodTables::nodes() const {
  if (!htNodes) throw Error("internal: HT node records used but not prepared");
  return *htNodes;
}

}  // namespace ht
