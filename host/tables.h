// The tables a method reads at every shading point. A render builds the ones
// its method needs before it starts (MethodSpec::prepare, through
// prepareTables in integrator.h), so that its time leaves them out, owns
// them, and passes them down: no process-wide caches. The HEALPix tree's
// geometry and packed nodes serve three families; any other table belongs
// to its method, which names its type.
#pragma once

#include <memory>
#include <typeinfo>

#include "error.h"

namespace ht {

struct HtGeometry;
struct HtNodes;

struct MethodTables {
  std::shared_ptr<const HtGeometry> htGeometry;  // ht*, ht-frontier, oracle: the map's order
  std::shared_ptr<const HtNodes> htNodes;        // ht*, ht-frontier on the CPU: geometry and trees packed

  // Each throws an internal ht::Error when its table was not prepared.
  const HtGeometry& geometry() const;
  const HtNodes& nodes() const;

  // The method's own table, of its own type.
  template <class T>
  void setOwn(std::shared_ptr<const T> table) {
    own_ = std::move(table);
    ownType_ = &typeid(T);
  }
  template <class T>
  std::shared_ptr<const T> ownPtr() const {
    if (!own_ || *ownType_ != typeid(T)) throw Error(std::string("internal: table used but not prepared: ") + typeid(T).name());
    return std::static_pointer_cast<const T>(own_);
  }
  template <class T>
  const T& own() const {
    return *ownPtr<T>();
  }
  // Which table it is, to tell when a device must upload it again.
  const void* ownId() const { return own_.get(); }

 private:
  std::shared_ptr<const void> own_;
  const std::type_info* ownType_ = nullptr;
};

}  // namespace ht
