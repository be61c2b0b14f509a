#include "common/files.h"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include <unistd.h>

namespace godhand {

namespace {

namespace fs = std::filesystem;

[[noreturn]] void meshFail(const std::string& path, const std::string& reason) {
  throw MeshError(path + ":0: " + reason);
}

}  // namespace

HandModel loadHandModel(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::error_code ec;  // a directory opens as an empty stream: refused by name, not as "no bodies"
  if (!in || fs::is_directory(path, ec)) throw ModelError(path + ": cannot open model file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return HandModel::fromText(ss.str(), path);
}

geo::TriangleMesh loadMeshFile(const std::string& path, MeshStats* stats) {
  std::error_code ec;
  if (!fs::exists(path, ec)) meshFail(path, "cannot open mesh file: no such file");
  if (!fs::is_regular_file(path, ec)) meshFail(path, "cannot open mesh file: not a regular file");
  meshFormat(path);  // a name that is neither .obj nor .stl is refused before the file is read
  std::ifstream in(path, std::ios::binary);
  if (!in) meshFail(path, std::string("cannot open mesh file: ") + std::strerror(errno));
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) meshFail(path, "read error");
  return parseMeshFile(bytes, path, stats);
}

MeshLoader meshFileLoader() {
  return [](const std::string& path) { return loadMeshFile(path); };
}

Scene loadScene(const std::string& path, const GodFidelity* god) {
  std::ifstream in(path, std::ios::binary);
  if (!in || fs::is_directory(path)) throw SceneError(path + ":0: cannot open scene file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parseScene(ss.str(), path, fs::path(path).parent_path().string(), meshFileLoader(), god);
}

std::string unwritableReason(const std::string& path) {
  if (path.empty()) return "empty file name";
  std::error_code ec;
  const fs::path p(path);
  if (fs::exists(p, ec)) {
    if (fs::is_directory(p, ec)) return "it is a directory";
    return ::access(path.c_str(), W_OK) == 0 ? "" : std::strerror(errno);
  }
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec)) return "no directory " + dir.string();
  return ::access(dir.c_str(), W_OK) == 0 ? "" : "directory " + dir.string() + ": " + std::strerror(errno);
}

}  // namespace godhand
