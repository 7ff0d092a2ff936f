#pragma once
/// handskin's own modules: libraries the build makes as MODULEs and the program loads at their
/// first use (libhandskin_step.so: Open CASCADE; libhandskin_pcl.so: PCL's file readers, its
/// voxel grid and its Poisson reconstruction), so that the ~20 and ~60 libraries behind them stay out of
/// every command's start.
#include <string>

namespace handskin {

/// A module opened (`handle`), or why it could not be (`failure`).
struct LoadedModule {
  void* handle = nullptr;
  std::string failure;
  /// An entry point by name (nullptr when the module lacks it or is not loaded).
  void* symbol(const char* name) const;
  /// Sets `fn` to the entry point `name`; when the module is loaded but lacks it, `failure`
  /// names it (so a loader binds its entries in a row, then looks at `failure` once).
  template <class Fn>
  void entry(Fn*& fn, const char* name) {
    fn = reinterpret_cast<Fn*>(symbol(name));
    if (handle && !fn) failure += (failure.empty() ? "" : "; ") + std::string("it lacks the entry point ") + name;
  }
};

/// Opens a module: where the build put it (`built_path`), else `file_name` beside the running
/// program (an installed or moved build). Each call opens it again (dlopen counts): callers keep
/// the result once, in a function-local static.
LoadedModule open_module(const std::string& built_path, const std::string& file_name);

}  // namespace handskin
