#include "scene/scene_file.h"

#include <google/protobuf/text_format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "model/text_proto.h"
#include "scene.pb.h"
#include "scene/mesh_io.h"

namespace godhand {

namespace {

constexpr size_t kMaxPhysicsHullVertices = 100;

namespace fs = std::filesystem;
using geo::MeshBvh;
using geo::TriangleMesh;
using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::TextFormat;

constexpr long long kMaxSubdividedTriangles = 50'000'000;


/// "SOURCE:LINE: PATH: " for field `name` of `msg` (index -1 for singular fields), falling back
/// to the enclosing message's line when the field is absent (same scheme as the hand model).
std::string locate(const std::string& source, const Message& msg, const TextFormat::ParseInfoTree* tree,
                   const std::string& name, int fallback_line, const std::string& path) {
  int line = fallback_line;
  const FieldDescriptor* f = msg.GetDescriptor()->FindFieldByName(name);
  if (tree && f) {
    const auto loc = tree->GetLocation(f, -1);
    if (loc.line >= 0) line = loc.line + 1;
  }
  return source + ":" + (line > 0 ? std::to_string(line) : "?") + ": " + path + ": ";
}

Vec3 toVec(const pb::Vec3& v) { return {v.x(), v.y(), v.z()}; }
bool finite(double x) { return std::isfinite(x); }

std::string num(double x) {
  std::ostringstream os;
  os.precision(6);
  os << x;
  return os.str();
}

/// Exact text of a double for cache keys.
std::string bits(double x) {
  uint64_t u;
  std::memcpy(&u, &x, sizeof u);
  return std::to_string(u);
}

std::shared_ptr<const MeshBvh> makeBvh(TriangleMesh mesh, bool solid = true) {
  auto bvh = std::make_shared<MeshBvh>(std::move(mesh));
  bvh->setSolid(solid);
  return bvh;
}

/// A mesh file at one scale / centring / subdivision: the full-resolution BVH and what the
/// other fidelities derive from.
struct MeshAsset {
  std::shared_ptr<const MeshBvh> full;
  TriangleMesh base;          ///< scaled and centred, before subdivision (same surface as full)
  geo::Aabb bounds;           ///< of base (= of full)
  double scale = 1.0;
  Vec3 translation = Vec3::Zero();
  std::optional<std::vector<Vec3>> hull_points;
  SurfaceVerdict surface;     ///< of the file's mesh (an inverted one is turned outward here)
  std::map<std::string, std::shared_ptr<const MeshBvh>> god;  ///< by fidelity key
  struct AutoChoice {
    std::shared_ptr<const MeshBvh> god;
    double skin = 0.0;
    std::string note;
  };
  std::map<std::string, AutoChoice> auto_choice;  ///< by tolerance
};

/// Everything loaded once per parseScene / meshScene call and shared between objects.
class Cache {
 public:
  explicit Cache(const MeshLoader& load_mesh) : load_mesh_(load_mesh) {}

  /// The cleaned mesh of a file (throws MeshError). Keyed by the path string as given: a
  /// canonical path would ask the file system (core does no I/O), and a lexical normalisation
  /// could merge two files ("link/../a.obj" is not "a.obj" when link is a symbolic link).
  const TriangleMesh& raw(const std::string& file) {
    auto it = raw_.find(file);
    if (it == raw_.end()) it = raw_.emplace(file, load_mesh_(file)).first;
    return it->second;
  }

  MeshAsset& asset(const std::string& file, double scale, bool centre, int subdiv) {
    const TriangleMesh& r = raw(file);
    const std::string key = file + "|" + bits(scale) + "|" + (centre ? "c" : "-") + "|" + std::to_string(subdiv);
    auto it = assets_.find(key);
    if (it != assets_.end()) return it->second;
    MeshAsset a;
    a.scale = scale;
    a.base = uniformScale(r, scale);
    if (centre) {
      a.translation = -meshBounds(a.base).centre();
      a.base = translate(std::move(a.base), a.translation);
    }
    a.bounds = meshBounds(a.base);
    // Inside and outside as the winding number sees them (mesh_io.h): a closed mesh facing
    // inwards is turned outward, an open surface becomes a shell (no inside).
    auto full = std::make_shared<MeshBvh>(subdiv > 0 ? subdivide(a.base, subdiv) : a.base);
    a.surface = classifySurface(*full);
    if (a.surface.kind == SurfaceVerdict::Kind::Inverted) {
      a.base = flipped(std::move(a.base));
      full = std::make_shared<MeshBvh>(subdiv > 0 ? subdivide(a.base, subdiv) : a.base);
    }
    full->setSolid(a.surface.kind != SurfaceVerdict::Kind::Shell);
    a.full = full;
    return assets_.emplace(key, std::move(a)).first->second;
  }

  const std::vector<Vec3>& hullPoints(MeshAsset& a) {
    // Bullet's convex-hull collision costs O(vertices) per support call and its multi-point
    // contacts call it many times: the bunny's 1,502-vertex hull took ~1 s per scene step. The
    // physics hull is therefore the hull of a decimated hull, at most ~100 vertices (within one
    // clustering cell of the true hull; the God-object collision never uses this hull).
    if (!a.hull_points) {
      TriangleMesh hull = convexHull(a.base.vertices);
      if (hull.vertices.size() > kMaxPhysicsHullVertices) hull = convexHull(decimate(hull, 150).vertices);
      a.hull_points = hull.vertices;
    }
    return *a.hull_points;
  }

  /// Tessellated primitive shared by identical primitives.
  std::shared_ptr<const MeshBvh> primitive(const std::string& key, const std::function<TriangleMesh()>& make) {
    auto it = primitives_.find(key);
    if (it == primitives_.end()) it = primitives_.emplace(key, makeBvh(make())).first;
    return it->second;
  }

 private:
  const MeshLoader& load_mesh_;
  std::map<std::string, TriangleMesh> raw_;
  std::map<std::string, MeshAsset> assets_;
  std::map<std::string, std::shared_ptr<const MeshBvh>> primitives_;
};

/// The God-side mesh of an asset at a fidelity (shared between objects that ask the same).
std::shared_ptr<const MeshBvh> godMesh(MeshAsset& a, pb::GodGeometry::Fidelity fidelity, int target_triangles) {
  using GF = pb::GodGeometry;
  const std::string gkey = std::to_string(static_cast<int>(fidelity)) + "|" + std::to_string(target_triangles);
  auto& god = a.god[gkey];
  if (!god) {
    switch (fidelity) {
      case GF::DECIMATED:
        god = a.full->triangleCount() <= target_triangles ? a.full
                                                          : makeBvh(decimate(a.full->mesh(), target_triangles), a.full->solid());
        break;
      case GF::CONVEX_HULL: god = makeBvh(convexHull(a.base.vertices)); break;
      case GF::PRIMITIVE: god = makeBvh(translate(boxMesh(0.5 * a.bounds.extent()), a.bounds.centre())); break;
      default: god = a.full; break;
    }
  }
  return god;
}

std::string thousands(long long n) {
  std::string d = std::to_string(n), out;
  for (size_t i = 0; i < d.size(); ++i) {
    if (i > 0 && (d.size() - i) % 3 == 0) out += ',';
    out += d[i];
  }
  return out;
}

std::string mm(double m) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g mm", m * 1e3);
  return buf;
}

/// Fidelity AUTO of a mesh asset: the coarsest of the hull and the decimations to 1/2, 1/4, ...
/// whose distance bound from the full surface is within `tolerance` (m), with that bound as the
/// God side's skin; none: the full mesh, skin 0.
const MeshAsset::AutoChoice& autoGod(MeshAsset& a, double tolerance) {
  const std::string key = bits(tolerance);
  auto it = a.auto_choice.find(key);
  if (it != a.auto_choice.end()) return it->second;
  MeshAsset::AutoChoice choice;
  const TriangleMesh& full = a.full->mesh();
  const int n = full.triangleCount();
  std::vector<int> targets;  // coarsest first
  for (int t = n / 2; t >= 64; t /= 2) targets.insert(targets.begin(), t);
  int tried = 0;
  std::string finest_tried;
  auto consider = [&](std::shared_ptr<const MeshBvh> god, const std::string& what) {
    double measured = 0.0;
    const double bound = geo::surfaceDistanceBound(full, *god, tolerance, &measured);
    if (bound <= tolerance) {
      choice.god = std::move(god);
      choice.skin = bound;
      choice.note = "AUTO " + mm(tolerance) + ": " + what + ", the full surface within " + mm(bound) +
                    " of it (bound; " + mm(measured) + " at the samples); God objects grown by " + mm(bound);
      return true;
    }
    ++tried;
    finest_tried = what;
    return false;
  };
  bool found = consider(makeBvh(convexHull(a.base.vertices)), "convex hull");
  for (size_t i = 0; !found && i < targets.size(); ++i) {
    std::shared_ptr<const MeshBvh> d = makeBvh(decimate(full, targets[i]), a.full->solid());
    if (d->triangleCount() >= n) break;
    found = consider(d, "decimated to " + thousands(d->triangleCount()) + " of " + thousands(n) + " triangles");
  }
  if (!found) {
    choice.god = a.full;
    choice.skin = 0.0;
    choice.note = "AUTO " + mm(tolerance) + ": the full mesh (" + thousands(n) + " triangles): no coarser level is within it (" +
                  std::to_string(tried) + " tried, the finest " + finest_tried + ")";
  }
  return a.auto_choice.emplace(key, std::move(choice)).first->second;
}

/// The God side of a mesh object as `g` asks (meshScene's spec, godhand-bench's --god-fidelity
/// over a scene file); `what` begins its errors.
void setGod(MeshAsset& a, const GodFidelity& g, const std::string& what, SceneObject* o) {
  using GF = pb::GodGeometry;
  o->god_skin = 0.0;
  o->god_note.clear();
  switch (g.kind) {
    case GodFidelity::Kind::Decimated:
      if (g.target_triangles < 4) throw SceneError(what + "decimation needs >= 4 triangles");
      o->god = godMesh(a, GF::DECIMATED, g.target_triangles);
      break;
    case GodFidelity::Kind::Hull: o->god = godMesh(a, GF::CONVEX_HULL, 0); break;
    case GodFidelity::Kind::Auto: {
      if (!(g.tolerance_m > 0.0)) throw SceneError(what + "AUTO needs a tolerance > 0");
      const MeshAsset::AutoChoice& c = autoGod(a, g.tolerance_m);
      o->god = c.god;
      o->god_skin = c.skin;
      o->god_note = c.note;
      break;
    }
    case GodFidelity::Kind::Full: o->god = a.full; break;
  }
}

void addTotals(Scene* scene) {
  scene->god_triangles = scene->reference_triangles = 0;
  for (size_t i = 0; i < scene->objects.size(); ++i) {
    SceneObject& o = scene->objects[i];
    o.index = static_cast<int>(i);
    scene->god_triangles += o.god->triangleCount();
    scene->reference_triangles += o.reference->triangleCount();
  }
}

/// The whole of `t` as a finite number, or nothing (empty, trailing characters, NaN, Inf).
std::optional<double> wholeNumber(const std::string& t) {
  size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(t, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (t.empty() || used != t.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

Scene parseScene(const std::string& text, const std::string& source, const std::string& base_dir,
                 const MeshLoader& load_mesh, const GodFidelity* god_override) {
  pb::Scene msg;
  TextFormat::ParseInfoTree tree;
  std::string syntax;
  if (!parseTextProto(text, &msg, &tree, &syntax, "unparsable scene")) throw SceneError(source + ":" + syntax);

  Scene scene;
  scene.name = msg.name().empty() ? fs::path(source).stem().string() : msg.name();
  if (msg.has_gravity()) {
    scene.gravity = toVec(msg.gravity());
    if (!scene.gravity.allFinite() || scene.gravity.norm() > 1000.0)
      throw SceneError(locate(source, msg, &tree, "gravity", 1, "gravity") + "must be finite and at most 1000 m/s² (100 g)");
  }
  if (msg.objects_size() == 0) throw SceneError(source + ":1: objects: a scene needs at least one object");

  const FieldDescriptor* f_objects = msg.GetDescriptor()->FindFieldByName("objects");
  Cache cache(load_mesh);
  std::set<std::string> ids;
  for (int i = 0; i < msg.objects_size(); ++i) {
    const pb::SceneObject& po = msg.objects(i);
    const TextFormat::ParseInfoTree* t = tree.GetTreeForNested(f_objects, i);
    const int line = tree.GetLocation(f_objects, i).line + 1;
    const std::string path = "objects[" + std::to_string(i) + "]";
    auto where = [&](const std::string& field) {
      return locate(source, po, t, field, line, path + (field.empty() ? "" : "." + field));
    };
    auto bad = [&](const std::string& field, const std::string& reason) { throw SceneError(where(field) + reason); };

    SceneObject o;
    o.id = po.id();
    if (o.id.empty()) bad("id", "every object needs an id");
    if (!ids.insert(o.id).second) bad("id", "duplicate object id '" + o.id + "'");

    o.mass = po.mass();
    if (!(o.mass >= 0.0 && o.mass <= 1e6)) bad("mass", "mass must lie in [0, 1e6] kg (0 = static), got " + num(o.mass));
    const bool dynamic = o.mass > 0.0;
    if (po.has_friction()) {
      o.friction = po.friction();
      if (!(o.friction >= 0.0 && o.friction <= 100.0)) bad("friction", "friction must lie in [0, 100], got " + num(o.friction));
    }
    if (po.has_restitution()) {
      o.restitution = po.restitution();
      if (!(o.restitution >= 0.0 && o.restitution <= 1.0))
        bad("restitution", "restitution must lie in [0, 1], got " + num(o.restitution));
    }
    o.X_WO.p = toVec(po.position());
    if (!o.X_WO.p.allFinite()) bad("position", "must be finite");
    if (po.has_orientation()) {
      const auto& q = po.orientation();
      const Quat qq(q.w(), q.x(), q.y(), q.z());
      if (!qq.coeffs().allFinite() || !(qq.norm() > 1e-6))
        bad("orientation", "must be a finite non-zero quaternion (w, x, y, z); it is normalised on load");
      o.X_WO.q = qq.normalized();
    }

    const bool is_mesh = po.geometry_case() == pb::SceneObject::kMesh;
    if (!is_mesh) {
      if (po.scaling_case() == pb::SceneObject::kScale) bad("scale", "scale applies to mesh objects only (give primitive dimensions directly)");
      if (po.scaling_case() == pb::SceneObject::kSize) bad("size", "size applies to mesh objects only (give primitive dimensions directly)");
      if (po.subdivide() != 0) bad("subdivide", "subdivide applies to mesh objects only");
      if (po.centre()) bad("centre", "centre applies to mesh objects only (primitives are centred)");
    }

    // God fidelity.
    using GF = pb::GodGeometry;
    if (!GF::Fidelity_IsValid(po.god().fidelity())) bad("god", "unknown fidelity " + std::to_string(static_cast<int>(po.god().fidelity())));
    if (!pb::PhysicsGeometry::Fidelity_IsValid(po.physics().fidelity()))
      bad("physics", "unknown fidelity " + std::to_string(static_cast<int>(po.physics().fidelity())));
    const GF::Fidelity god_f = po.god().fidelity() == GF::FIDELITY_DEFAULT ? GF::FULL : po.god().fidelity();
    if (god_f == GF::DECIMATED && (po.god().target_triangles() < 4 || po.god().target_triangles() > 100000000))
      bad("god", "DECIMATED needs target_triangles in [4, 100000000], got " + std::to_string(po.god().target_triangles()));
    if (god_f != GF::DECIMATED && po.god().target_triangles() != 0)
      bad("god", "target_triangles applies to DECIMATED only");
    const bool tolerance_set = po.god().tolerance_mm() != 0.0;
    if (god_f == GF::AUTO && tolerance_set && !(po.god().tolerance_mm() > 0.0 && po.god().tolerance_mm() <= 1000.0))
      bad("god", "AUTO needs tolerance_mm in (0, 1000], got " + num(po.god().tolerance_mm()));
    if (god_f != GF::AUTO && tolerance_set) bad("god", "tolerance_mm applies to AUTO only");
    const double auto_tolerance = (tolerance_set ? po.god().tolerance_mm() : 3.0) * 1e-3;

    // Physics fidelity.
    using PF = pb::PhysicsGeometry;
    PF::Fidelity phys_f = po.physics().fidelity();
    if (phys_f == PF::FIDELITY_DEFAULT) phys_f = !is_mesh ? PF::PRIMITIVE : dynamic ? PF::CONVEX_HULL : PF::TRIANGLE_MESH;
    if (dynamic && phys_f == PF::TRIANGLE_MESH)
      bad("physics", "TRIANGLE_MESH physics is for static objects only (mass 0); use CONVEX_HULL or PRIMITIVE for a dynamic object");
    if (dynamic && phys_f == PF::NONE) bad("physics", "a dynamic object (mass > 0) needs a physics shape, not NONE");

    switch (po.geometry_case()) {
      case pb::SceneObject::kMesh: {
        if (po.mesh().empty()) bad("mesh", "empty mesh path");
        const fs::path p(po.mesh());
        const std::string file = (p.is_absolute() ? p : fs::path(base_dir) / p).lexically_normal().string();
        o.source = file;
        const unsigned subdiv = po.subdivide();
        try {
          const TriangleMesh& raw = cache.raw(file);
          double scale = 1.0;
          if (po.scaling_case() == pb::SceneObject::kScale) {
            scale = po.scale();
            if (!(scale >= 1e-9 && scale <= 1e9)) bad("scale", "scale must lie in [1e-9, 1e9], got " + num(scale));
          } else if (po.scaling_case() == pb::SceneObject::kSize) {
            if (!(po.size() >= 1e-6 && po.size() <= 1e3)) bad("size", "size must lie in [1e-6, 1000] m, got " + num(po.size()));
            const double extent = meshBounds(raw).extent().maxCoeff();
            if (!(extent > 0.0)) bad("size", "the mesh has zero extent");
            scale = po.size() / extent;
          }
          if (subdiv > 6 || static_cast<long long>(raw.triangles.size()) << (2 * subdiv) > kMaxSubdividedTriangles)
            bad("subdivide", std::to_string(subdiv) + " levels would give " +
                                 num(static_cast<double>(raw.triangles.size()) * std::pow(4.0, subdiv)) +
                                 " triangles (limit " + std::to_string(kMaxSubdividedTriangles) + ")");
          MeshAsset& a = cache.asset(file, scale, po.centre(), static_cast<int>(subdiv));
          o.scale = a.scale;
          o.translation = a.translation;
          o.reference = a.full;
          o.surface_note = a.surface.describe();
          o.surface_changed = a.surface.kind != SurfaceVerdict::Kind::Solid;
          if (god_override) {
            setGod(a, *god_override, where("god") + "(the --god-fidelity given instead) ", &o);
          } else if (god_f == GF::AUTO) {
            const MeshAsset::AutoChoice& c = autoGod(a, auto_tolerance);
            o.god = c.god;
            o.god_skin = c.skin;
            o.god_note = c.note;
          } else {
            o.god = godMesh(a, god_f, static_cast<int>(po.god().target_triangles()));
          }
          switch (phys_f) {
            case PF::TRIANGLE_MESH:
              o.physics.type = PhysicsShapeType::TriangleMesh;
              o.physics.mesh = a.base;
              break;
            case PF::CONVEX_HULL:
              o.physics.type = PhysicsShapeType::ConvexHull;
              o.physics.points = cache.hullPoints(a);
              break;
            case PF::PRIMITIVE:
              if (a.bounds.centre().norm() > 1e-9 * a.bounds.extent().maxCoeff())
                bad("physics", "PRIMITIVE physics of a mesh is its bounding box, which must be centred at the object origin: add `centre: true`");
              o.physics.type = PhysicsShapeType::Box;
              o.physics.half_extents = 0.5 * a.bounds.extent();
              break;
            default: o.physics.type = PhysicsShapeType::None; break;
          }
        } catch (const SceneError&) {
          throw;
        } catch (const MeshError& e) {
          bad("mesh", e.what());
        } catch (const std::exception& e) {
          bad("mesh", std::string(po.mesh()) + ": " + e.what());
        }
        break;
      }
      case pb::SceneObject::kBox:
      case pb::SceneObject::kSphere:
      case pb::SceneObject::kCylinder: {
        std::string key;
        std::function<TriangleMesh()> make;
        if (po.has_box()) {
          const Vec3 e = toVec(po.box().half_extents());
          if (!e.allFinite() || !(e.minCoeff() >= 1e-6 && e.maxCoeff() <= 100.0))
            bad("box", "box needs all half_extents in [1e-6, 100] m");
          o.physics.half_extents = e;
          o.source = "box " + num(2 * e.x()) + " x " + num(2 * e.y()) + " x " + num(2 * e.z()) + " m";
          key = "box|" + bits(e.x()) + "|" + bits(e.y()) + "|" + bits(e.z());
          make = [e] { return boxMesh(e); };
        } else if (po.has_sphere()) {
          const double r = po.sphere().radius();
          if (!(r >= 1e-6 && r <= 100.0)) bad("sphere", "sphere needs a radius in [1e-6, 100] m");
          o.physics.radius = r;
          o.source = "sphere r " + num(r) + " m";
          key = "sphere|" + bits(r);
          make = [r] { return sphereMesh(r); };
        } else {
          const double r = po.cylinder().radius(), h = po.cylinder().half_height();
          if (!(r >= 1e-6 && r <= 100.0 && h >= 1e-6 && h <= 100.0))
            bad("cylinder", "cylinder needs radius and half_height in [1e-6, 100] m");
          o.physics.half_extents = Vec3(r, r, h);
          o.source = "cylinder r " + num(r) + " m, height " + num(2 * h) + " m";
          key = "cylinder|" + bits(r) + "|" + bits(h);
          make = [r, h] { return cylinderMesh(r, h); };
        }
        o.god = o.reference = cache.primitive(key, make);
        if (god_f == GF::AUTO) o.god_note = "AUTO: a primitive's tessellation (it encloses the primitive: nothing coarser)";
        switch (phys_f) {
          case PF::PRIMITIVE:
            o.physics.type = po.has_box() ? PhysicsShapeType::Box : po.has_sphere() ? PhysicsShapeType::Sphere : PhysicsShapeType::Cylinder;
            break;
          case PF::CONVEX_HULL:
            o.physics.type = PhysicsShapeType::ConvexHull;
            o.physics.points = o.god->mesh().vertices;
            break;
          case PF::TRIANGLE_MESH:
            o.physics.type = PhysicsShapeType::TriangleMesh;
            o.physics.mesh = o.god->mesh();
            break;
          default: o.physics.type = PhysicsShapeType::None; break;
        }
        if (o.physics.type != PhysicsShapeType::Box && o.physics.type != PhysicsShapeType::Cylinder)
          o.physics.half_extents = Vec3::Zero();
        if (o.physics.type != PhysicsShapeType::Sphere) o.physics.radius = 0.0;
        break;
      }
      default:
        bad("", "object '" + o.id + "' has no geometry (mesh, box, sphere or cylinder)");
    }
    scene.objects.push_back(std::move(o));
  }
  addTotals(&scene);
  return scene;
}

MeshSpec parseMeshSpec(const std::string& whole) {
  MeshSpec spec;
  std::string arg = whole;
  // "@X,Y,Z": where the mesh's centre goes (a path may contain '@': only a tail of three numbers
  // is a position).
  if (const size_t at = arg.rfind('@'); at != std::string::npos) {
    const std::string tail = arg.substr(at + 1);
    std::vector<double> v;
    size_t pos = 0;
    for (;;) {
      const size_t comma = tail.find(',', pos);
      const std::optional<double> x = wholeNumber(tail.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos));
      if (!x) break;
      v.push_back(*x);
      if (comma == std::string::npos) break;
      pos = comma + 1;
    }
    // A tail of three comma-separated words is a position (nan and inf included, to be refused
    // as such rather than taken for part of the file name).
    auto numberWord = [](std::string w) {  // a number, or nan / inf written as one
      for (char& ch : w) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      if (!w.empty() && (w[0] == '+' || w[0] == '-')) w.erase(0, 1);
      return w == "nan" || w == "inf" || w == "infinity" ||
             (!w.empty() && w.find_first_not_of("0123456789.e+-") == std::string::npos);
    };
    bool numbers_only = std::count(tail.begin(), tail.end(), ',') == 2;
    for (size_t a = 0; numbers_only;) {
      const size_t comma = tail.find(',', a);
      numbers_only = numberWord(tail.substr(a, comma == std::string::npos ? std::string::npos : comma - a));
      if (comma == std::string::npos) break;
      a = comma + 1;
    }
    numbers_only = numbers_only || tail.find_first_not_of("0123456789+-.,eE") == std::string::npos;
    if (numbers_only && !tail.empty()) {
      if (v.size() != 3 || !Vec3(v[0], v[1], v[2]).allFinite() || Vec3(v[0], v[1], v[2]).cwiseAbs().maxCoeff() > 1e6)
        throw SceneError("--mesh " + whole + ": position '" + tail + "' must be three finite numbers of metres (FILE[:SIZE_M]@X,Y,Z)");
      spec.at = Vec3(v[0], v[1], v[2]);
      arg = arg.substr(0, at);
    }
  }
  spec.path = arg;
  const size_t colon = arg.rfind(':');
  if (colon != std::string::npos) {
    const std::string tail = arg.substr(colon + 1);
    const std::string lt = lower(tail);
    const bool is_path = tail.find('/') != std::string::npos ||
                         (lt.size() >= 4 && (lt.compare(lt.size() - 4, 4, ".obj") == 0 || lt.compare(lt.size() - 4, 4, ".stl") == 0));
    if (!is_path) {
      spec.path = arg.substr(0, colon);
      const double size = wholeNumber(tail).value_or(0.0);
      if (!(size > 0.0) || size > 1e3)
        throw SceneError("--mesh " + whole + ": size '" + tail + "' must be a positive number of metres (FILE[:SIZE_M], e.g. bunny.obj:0.15)");
      spec.size = size;
    }
  }
  if (spec.path.empty()) throw SceneError("--mesh " + whole + ": empty mesh path (FILE[:SIZE_M])");
  return spec;
}

GodFidelity parseGodFidelity(const std::string& arg) {
  GodFidelity g;
  const std::string a = lower(arg);
  if (a == "full") return g;
  if (a == "hull") {
    g.kind = GodFidelity::Kind::Hull;
    return g;
  }
  auto after = [&](const std::string& prefix) {
    return a.compare(0, prefix.size(), prefix) == 0 ? wholeNumber(a.substr(prefix.size())) : std::nullopt;
  };
  if (const std::optional<double> mm = after("auto:"); mm && *mm > 0.0 && *mm <= 1000.0) {
    g.kind = GodFidelity::Kind::Auto;
    g.tolerance_m = *mm * 1e-3;
    return g;
  }
  if (const std::optional<double> n = after("decimated:"); n && *n >= 4.0 && *n <= 1e8 && *n == std::floor(*n)) {
    g.kind = GodFidelity::Kind::Decimated;
    g.target_triangles = static_cast<int>(*n);
    return g;
  }
  throw SceneError("God-side fidelity '" + arg + "': expected full, hull, decimated:N (N >= 4 triangles) or auto:MM (tolerance in mm, > 0)");
}

Scene meshScene(const std::vector<MeshSpec>& specs, const Vec3& centre, const MeshLoader& load_mesh) {
  if (specs.empty()) throw SceneError("--mesh: no mesh given");
  if (!centre.allFinite()) throw SceneError("--mesh: the centre must be finite");
  Cache cache(load_mesh);
  Scene scene;
  std::map<std::string, int> stems;
  for (const MeshSpec& spec : specs) {
    if (!(spec.size > 0.0 && finite(spec.size)))
      throw SceneError("--mesh " + spec.path + ": size must be a positive number of metres, got " + num(spec.size));
    SceneObject o;
    try {
      const TriangleMesh& raw = cache.raw(spec.path);
      const double extent = meshBounds(raw).extent().maxCoeff();
      if (!(extent > 0.0)) throw SceneError("--mesh " + spec.path + ": the mesh has zero extent");
      MeshAsset& a = cache.asset(spec.path, spec.size / extent, true, 0);
      o.reference = a.full;
      o.surface_note = a.surface.describe();
      o.surface_changed = a.surface.kind != SurfaceVerdict::Kind::Solid;
      setGod(a, spec.god, "--mesh " + spec.path + ": ", &o);
      o.scale = a.scale;
      o.translation = a.translation;
      o.physics.type = PhysicsShapeType::TriangleMesh;
      o.physics.mesh = a.base;
    } catch (const MeshError& e) {
      throw SceneError(e.what());
    } catch (const SceneError&) {
      throw;
    } catch (const std::exception& e) {
      throw SceneError("--mesh " + spec.path + ": " + e.what());
    }
    std::string id = fs::path(spec.path).stem().string();
    if (id.empty()) id = "mesh";
    const int n = ++stems[id];
    if (n > 1) id += "_" + std::to_string(n);
    o.id = id;
    o.source = spec.path;
    o.X_WO.p = spec.at ? *spec.at : centre;
    o.mass = 0.0;
    scene.objects.push_back(std::move(o));
    if (!scene.name.empty()) scene.name += ", ";
    scene.name += fs::path(spec.path).filename().string();
  }
  scene.name = "mesh: " + scene.name;
  addTotals(&scene);
  return scene;
}

}  // namespace godhand
