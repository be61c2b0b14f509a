// libFuzzer target: the mesh parsers of core/scene (OBJ text, STL ASCII and binary) and the
// cleaning every loaded mesh goes through. The first input byte picks the parser (bit 0: STL,
// else OBJ). A bad file is one MeshError line; a parsed mesh has finite vertices and every index
// in range, and its cleaned form too.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "scene/mesh_io.h"

namespace {
void checkMesh(const godhand::geo::TriangleMesh& m) {
  for (const godhand::Vec3& v : m.vertices)
    if (!v.allFinite()) std::abort();
  const long nv = static_cast<long>(m.vertices.size());
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k)
      if (t[k] < 0 || t[k] >= nv) std::abort();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string body(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    godhand::MeshStats stats;
    const godhand::geo::TriangleMesh m =
        (data[0] & 1) ? godhand::parseStl(body, "fuzz", &stats) : godhand::parseObj(body, "fuzz", &stats);
    checkMesh(m);
    checkMesh(godhand::cleanMesh(m));
  } catch (const godhand::MeshError& e) {
    const std::string what = e.what();
    if (what.empty() || what.find('\n') != std::string::npos) std::abort();
  }
  return 0;
}
