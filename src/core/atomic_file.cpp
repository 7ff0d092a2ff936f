#include "core/atomic_file.hpp"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "core/errors.hpp"

namespace fs = std::filesystem;

namespace handskin {

std::string temp_name_for(const std::string& path) {
  const fs::path p(path);
  return (p.parent_path() / ("." + p.stem().string() + ".tmp" + std::to_string(::getpid()) + p.extension().string()))
      .string();
}

std::string name_of_temp(const std::string& name) {
  const std::string tmp = ".tmp" + std::to_string(::getpid());
  const size_t at = name.find(tmp);
  if (name.size() < 2 || name[0] != '.' || at == std::string::npos) return name;
  return name.substr(1, at - 1) + name.substr(at + tmp.size());
}

void write_via_temp(const std::string& path, const std::function<void(const std::string& tmp)>& writer) {
  // The folder is checked first: library writers (PCL, OpenMesh) report a missing folder in
  // their own words, or by an exception of their own type.
  const fs::path dir = fs::path(path).parent_path();
  std::error_code dir_ec;
  if (!dir.empty() && !fs::is_directory(dir, dir_ec))
    throw InputError(path, "cannot write: folder '" + dir.string() + "' does not exist");
  const std::string tmp = temp_name_for(path);
  auto remove_tmp = [&] {
    std::error_code ignored;  // its own code: the cleanup must not overwrite the cause
    fs::remove(tmp, ignored);
  };
  try {
    writer(tmp);
  } catch (const InputError&) {
    remove_tmp();
    throw;
  } catch (const std::exception& e) {
    remove_tmp();
    throw InputError(path, std::string("cannot write: ") + e.what());
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    const std::string cause = ec.message();
    remove_tmp();
    throw InputError(path, "cannot write: " + cause);
  }
}

void write_file_atomic(const std::string& path, const std::string& bytes) {
  write_via_temp(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) {
      const int cause = errno;
      throw InputError(path, std::string("cannot open for writing: ") + std::strerror(cause));
    }
    errno = 0;
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) {  // the system's cause when the stream's write call left one (ENOSPC, EFBIG, EIO)
      const int cause = errno;
      throw InputError(path, cause ? std::string("write failed: ") + std::strerror(cause) : std::string("write failed (disk full?)"));
    }
  });
}

std::string read_file(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path, "no such file");
  if (fs::is_directory(path, ec)) throw InputError(path, "is a directory, expected a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(path, "read failed");
  return ss.str();
}

void ensure_directory(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec || !fs::is_directory(path)) throw InputError(path, "cannot create output directory: " + ec.message());
}

}  // namespace handskin
