#pragma once
/// Small helpers on file paths.
#include <cctype>
#include <filesystem>
#include <string>

namespace handskin {

/// A path's extension in lower case with its dot (".ply"; "" when there is none): what every
/// reader and writer that goes by extension compares.
inline std::string lower_extension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

}  // namespace handskin
