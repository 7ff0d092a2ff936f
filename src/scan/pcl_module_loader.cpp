#include "core/module.hpp"
#include "scan/pcl_module.hpp"

namespace handskin {

const PclModule& pcl_module() {
  static const PclModule m = [] {
    PclModule m;
    const LoadedModule lib = open_module(HANDSKIN_PCL_MODULE, "libhandskin_pcl.so");
    m.failure = lib.failure;
    if (!lib.handle) return m;
    m.read = reinterpret_cast<decltype(m.read)>(lib.symbol("handskin_pcl_read"));
    m.poisson = reinterpret_cast<decltype(m.poisson)>(lib.symbol("handskin_pcl_poisson"));
    if (!m.read || !m.poisson) m.failure = "libhandskin_pcl.so lacks its entry points";
    return m;
  }();
  return m;
}

}  // namespace handskin
