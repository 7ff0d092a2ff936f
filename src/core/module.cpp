#include "core/module.hpp"

#include <dlfcn.h>

#include <filesystem>
#include <vector>

namespace handskin {

void* LoadedModule::symbol(const char* name) const { return handle ? dlsym(handle, name) : nullptr; }

LoadedModule open_module(const std::string& built_path, const std::string& file_name) {
  std::vector<std::string> places = {built_path};
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::string beside = (exe.parent_path() / file_name).string();
    if (beside != built_path) places.push_back(beside);
  }
  LoadedModule m;
  for (const std::string& p : places) {
    if ((m.handle = dlopen(p.c_str(), RTLD_NOW | RTLD_LOCAL))) {
      m.failure.clear();
      return m;
    }
    m.failure += (m.failure.empty() ? "" : "; ") + std::string(dlerror());
  }
  return m;
}

}  // namespace handskin
