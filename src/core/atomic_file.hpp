#pragma once
/// Whole-file writes that never leave a half-written output: data goes to a temporary
/// file beside the target, which is renamed over it only once complete.
#include <functional>
#include <string>

namespace handskin {

/// The temporary name write_via_temp uses for `path`: `.<stem>.tmp<pid><ext>` beside it.
std::string temp_name_for(const std::string& path);
/// The file name a temporary's file name stands for (`.skin.tmp4711.ply` → `skin.ply`, for this
/// process's temporaries); any other name as it is.
std::string name_of_temp(const std::string& name);

/// Write `bytes` to `path` atomically. Throws InputError naming `path` on failure.
void write_file_atomic(const std::string& path, const std::string& bytes);

/// Call `writer(tmp_path)` to produce the file under a temporary name, then rename it to
/// `path`. If the writer throws or the rename fails, the temporary is removed and
/// nothing appears at `path`. The temporary keeps `path`'s extension (for writers that
/// look at it).
void write_via_temp(const std::string& path, const std::function<void(const std::string& tmp)>& writer);

/// Read a whole file. Throws InputError naming `path` when it cannot be read.
std::string read_file(const std::string& path);

/// Create a directory (and parents). Throws InputError naming `path` on failure.
void ensure_directory(const std::string& path);

}  // namespace handskin
