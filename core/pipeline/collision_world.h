// The God-object collision stage against the scene (METHOD.md §2 step 5, paper §6.2–6.3): contact
// generation, continuous collision (sweeps) and the exact penetration figure, over every scene
// object's triangle-mesh BVH at the object's current pose.
//
// Contacts (paper Eq. 24 rows, thinned as METHOD.md §3 asks): for each object whose box is within
// `reach` of a God object, exact closest-point queries on the BVH for the whole shape and for
// its parts (a capsule's two end spheres, a box's eight corners and twelve edge midpoints) give up to 21 candidate
// triangles, independent of the mesh's density (a dense mesh has thousands of triangles within
// a centimetre of a phalanx; taking all of them cost milliseconds and gave redundant rows). Per
// (body, object) pair at most K are kept, greedily in order of distance, skipping one whose
// point lies within `spread` of a kept one with a normal within `normal_angle` of it.
// Normals point from the object towards the God object. Meshes are hollow to distance queries:
// for dynamic objects (the only ones that can move onto a God object) the winding number of the
// body origin decides inside/outside, and a body found inside gets its normals flipped and its
// distances made negative, so that its rows push it out instead of further in.
//
// Penetration (METHOD.md §5): depth against the full-resolution reference meshes. While the
// cores are apart it is the rounded shell's overlap max(0, −d), d the exact shape–mesh distance.
// Where they cross (or the body's origin is inside, winding number > ½) it is the depth of the
// deepest witness: a point of the body's core (centre, ends, corners, points along its edges)
// inside the mesh (its distance to the surface plus the radius), or a point of a mesh edge near
// the body inside the body (deepest point per edge by golden-section search, exact for the
// concave depth of a convex shape). Two solids overlap only where an edge of one crosses the
// other, so this sees a cube's corner in a palm's face and a bar's edge across it, which the
// distance alone reads as touching. The scene's push-out and the start search use the same
// measure on the God meshes (signedDistance).
//
// What a scene requires (issue 14): every query first asks a box tree over the objects' boxes
// which objects it can reach, so an object no God object comes near costs no query at all (a
// thousand far objects add nothing measurable; the answers are the same as a scan over every
// object: candidates are visited in index order). Each object's share of the God side is
// measured: the time of its contact, sweep and distance queries (one clock read per object
// queried, none per triangle), `costs()`. Penetration is a measurement, not the method: it is
// not counted, nor is what runs under an `Untimed` guard (the run metrics' own sweeps).
// Not thread-safe: one thread at a time per world (each stage has its own).
#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

#include "geometry/bvh.h"
#include "geometry/sweep.h"
#include "scene/scene.h"
#include "step/constraints.h"

namespace godhand {

struct ContactParams {
  int per_pair = 8;             ///< K: contacts kept per (God object, scene object)
  double spread = 0.004;        ///< m: closer kept points must differ in normal
  /// The spread grows with the body: at least this fraction of its bounding radius (a palm
  /// touching along an edge keeps rows at its far corners instead of a row every few mm there).
  double spread_fraction = 0.25;
  double normal_angle = 0.35;   ///< rad: normals closer than this count as the same direction
  /// m: when the body is this close to an object, every triangle within the shell is a candidate
  /// too (a body in a crease touches two faces, and the closest-point queries find only one; a
  /// row for the nearest face alone pushes it into the other).
  double shell = 3e-4;
};

/// One object's share of the God side (CollisionWorld::costs).
struct ObjectCost {
  double us = 0.0;              ///< time of its contact, sweep and distance queries
  std::uint64_t queries = 0;    ///< queries that reached it (its box near the God object)
};

class CollisionWorld {
 public:
  /// The scene must outlive the world (its BVHs are shared, not copied).
  explicit CollisionWorld(const Scene& scene);

  /// Per object (scene order): what its queries cost so far.
  const std::vector<ObjectCost>& costs() const { return costs_; }
  /// Objects the broad phase handed to queries so far (each one costs a box test; a scan would
  /// hand every object to every query).
  std::uint64_t objectsVisited() const { return visited_; }
  void resetCosts();
  /// While one lives, queries of `world` are not counted in its costs (measurements that use the
  /// method's queries, e.g. the run metrics' stuck-frame sweeps).
  class Untimed {
   public:
    explicit Untimed(const CollisionWorld& world) : world_(world) { ++world_.untimed_; }
    ~Untimed() { --world_.untimed_; }
    Untimed(const Untimed&) = delete;
    Untimed& operator=(const Untimed&) = delete;

   private:
    const CollisionWorld& world_;
  };

  int objectCount() const { return static_cast<int>(objects_.size()); }
  /// The bounding radius of the shape as the God side sees it (grown by the largest skin of the
  /// scene's objects): how far a point of it moves per radian of a turn.
  double godBoundingRadius(const Shape& shape) const;
  void setObjectPose(int object, const Pose& X_WO);
  const Pose& objectPose(int object) const { return objects_[static_cast<size_t>(object)].X_WO; }
  const geo::Aabb& objectBox(int object) const { return objects_[static_cast<size_t>(object)].box_W; }

  /// What a contact query found of the whole shape, for a sweep that starts at the same pose
  /// (its d(0), geo::SweepStart): per object queried, the nearest triangle within the query's
  /// range; every object not listed has nothing within `reach` of the shape.
  struct QueryStart {
    double reach = 0.0;
    std::vector<std::pair<int, geo::SweepStart>> objects;
  };

  /// Appends the thinned contacts of God object `body` (shape at X_WB) with every object within
  /// `reach` (m). Keys identify (object, triangle, body) for warm starts. Returns the number added.
  /// `start` (optional) receives what the query found for a sweep from X_WB (QueryStart).
  int contacts(const Shape& shape, const Pose& X_WB, int body, double reach, const ContactParams& params,
               std::vector<Contact>* out, QueryStart* start = nullptr);
  /// The contact `c` (found by contacts(): its object, triangle, body and key) measured again
  /// with the body's shape at X_WB: false where its object or triangle is gone or the body is
  /// inside the object.
  bool triangleContact(const Shape& shape, const Pose& X_WB, const Contact& c, Contact* out) const;

  /// Time of contact of the motion X_W0 → X_W1 against every object it can reach (objects held
  /// at their current poses). `object_hit` (optional) receives the object that limits it, or −1.
  /// `start` (optional): a contact query's QueryStart at exactly X_W0 with the objects where they
  /// are now; each object's sweep then takes its d(0) from it (the same answer, one query fewer).
  geo::SweepResult sweep(const Shape& shape, const Pose& X_W0, const Pose& X_W1, const geo::SweepParams& params,
                         int* object_hit = nullptr, const QueryStart* start = nullptr) const;

  /// Exact penetration depth (≥ 0, m) against the reference meshes; `object` gets the deepest.
  double penetration(const Shape& shape, const Pose& X_WB, int* object = nullptr) const;
  /// Smallest signed distance (m) to the God-collision meshes within `range` (inside ⇒ < 0):
  /// +inf when nothing is within range.
  double clearance(const Shape& shape, const Pose& X_WB, double range) const;
  /// The same against the full-resolution reference meshes, with the shape as it is (no skin):
  /// how far the God object really is from the true surface (a measurement, not counted in costs).
  double referenceClearance(const Shape& shape, const Pose& X_WB, double range) const;
  /// Signed distance (m, inside ⇒ < 0) of the shape to one object's God mesh within `range`
  /// (+inf beyond), and the unit normal from the object towards the shape (world).
  double signedDistance(int object, const Shape& shape, const Pose& X_WB, double range, Vec3* n_W) const;
  /// signedDistance(object, shape, X_WB, range, ·) < range, without measuring how deep an
  /// overlap is (range > 0: any overlap is closer).
  bool closerThan(int object, const Shape& shape, const Pose& X_WB, double range) const;

 private:
  struct Object;
  /// How deep the shape at X_WB is in a mesh at X_WO (m, ≥ 0) and the unit direction from the
  /// object towards the shape (the object leaves the overlap along −n_W).
  struct Overlap {
    double depth = 0.0;
    Vec3 n_W = Vec3::UnitZ();
  };
  /// origin_known: 1 / 0 when the caller already knows whether the body's origin is inside the
  /// mesh (its winding number), −1 to have it computed here. `nearest` (origin outside only): the
  /// caller's own closest(shape, X_OB, range) answer, found within some range ≥ 0 with the cores
  /// crossing; the same triangle and points as this function's own query within 0 (the least
  /// distance is below both ranges), so that query is not made a second time.
  Overlap overlapIn(const geo::MeshBvh& mesh, const Pose& X_WO, const Shape& shape, const Pose& X_WB,
                    int origin_known = -1, const geo::NearTriangle* nearest = nullptr) const;
  /// Exact depth (≥ 0, m) of the shape in one object's reference mesh.
  double depthIn(const Object& o, const Shape& shape, const Pose& X_WB) const;
  /// A motion of a body that starts inside `o` ends, or passes a quarter point, deeper in it.
  bool deeperAlong(const Object& o, const Shape& shape, const Pose& X_W0, const Pose& X_W1) const;
  static constexpr double kDeeperTolerance = 1e-9;  ///< m: round-off of the depth
  struct Object {
    const geo::MeshBvh* god = nullptr;
    const geo::MeshBvh* reference = nullptr;
    Pose X_WO;
    geo::Aabb box_W;       ///< of the God mesh at X_WO, grown by the skin
    geo::Aabb ref_box_W;   ///< of the reference mesh at X_WO
    double skin = 0.0;     ///< SceneObject::god_skin: God-side queries use the shape grown by it
    bool dynamic = false;
  };
  bool insideGod(const Object& o, const Pose& X_OB) const;

  void place(size_t object, const Pose& X_WO);
  double nearest(bool reference, const Shape& shape, const Pose& X_WB, double range) const;

  /// The objects whose God or reference box may overlap `query`, ascending, in cand_.
  const std::vector<int>& candidates(const geo::Aabb& query) const;
  /// The box tree over the objects' boxes (God ∪ reference): nodes in pre-order (children after
  /// their parent), a leaf holds one object. A moved object's leaf and its ancestors are refitted
  /// at the next query; the tree is rebuilt once kRebuildFactor times as many boxes moved as it has
  /// objects (at least kRebuildAfter), or when an object without a box gets one (a tree's shape
  /// only changes how fast it answers, never what).
  struct Node {
    geo::Aabb box;
    int parent = -1;
    int right = -1;   ///< inner node: its right child (the left one is the next node)
    int object = -1;  ///< leaf: the object
  };
  void buildTree() const;
  int buildNode(int* ids, int count, int parent) const;
  void refitTree() const;
  static constexpr int kLinearUpTo = 8;       ///< up to this many objects: a plain scan
  static constexpr std::size_t kRebuildAfter = 256;
  static constexpr std::size_t kRebuildFactor = 8;
  mutable std::vector<Node> nodes_;
  mutable std::vector<int> build_ids_;
  mutable std::vector<int> leaf_of_;          ///< per object: its leaf node, -1 when none
  mutable std::vector<double> split_key_;     ///< per object: scratch of buildNode
  mutable std::vector<geo::Aabb> union_box_;  ///< per object: box_W ∪ ref_box_W
  mutable std::vector<int> moved_;            ///< objects whose box changed since the last query
  mutable std::vector<unsigned char> is_moved_;
  mutable bool rebuild_ = true;
  mutable std::size_t moved_since_build_ = 0;
  mutable std::vector<int> cand_, stack_;     // scratch
  // contacts(): per (object, body, part sample), the triangle its closest-point query found last
  // (−1: none), the next query's hint. Bodies 0 … kHintBodies − 1 only. A direct-mapped table of
  // kHintSlots objects (slot object % kHintSlots, tagged with its object), allocated with the
  // world: a hint only shortens a query (MeshBvh::closest finds the same triangle without it), so
  // objects sharing a slot cost time, never results, and no query allocates.
  static constexpr int kHintBodies = 64;
  static constexpr int kHintSlots = 32;
  std::vector<int> hints_;      ///< slots × kHintBodies × part samples
  std::vector<int> hint_tag_;   ///< per slot: its object, -1 when none
  int scratch_hint_ = -1;
  int& hintOf(int object, int body, int sample);

  /// Charges each queried object the time since the previous charge (or since begin()):
  /// one clock read per object.
  class CostClock {
   public:
    explicit CostClock(const CollisionWorld& w) : w_(w), on_(w.untimed_ == 0) {}
    void charge(size_t object);
    void begin() {
      if (on_ && !started_) {
        t_ = std::chrono::steady_clock::now();
        started_ = true;
      }
    }

   private:
    const CollisionWorld& w_;
    bool on_, started_ = false;
    std::chrono::steady_clock::time_point t_;
  };
  /// Begins timing an object's query at construction, charges it at destruction.
  struct Charge {
    Charge(CostClock& c, size_t o) : clock(c), object(o) { clock.begin(); }
    ~Charge() { clock.charge(object); }
    Charge(const Charge&) = delete;
    Charge& operator=(const Charge&) = delete;
    CostClock& clock;
    size_t object;
  };
  mutable std::vector<ObjectCost> costs_;
  mutable std::uint64_t visited_ = 0;
  mutable int untimed_ = 0;
  /// signedDistance's query box of its last call (callers loop over objects for one body).
  struct BoxMemo {
    bool valid = false;
    Shape shape;
    Pose X;
    double range = 0.0;
    geo::Aabb box;
  };
  mutable BoxMemo memo_;
  double max_skin_ = 0.0;  // the largest SceneObject::god_skin

  std::vector<Object> objects_;
  std::vector<geo::NearTriangle> near_, shell_;  // scratch
  std::vector<int> order_, sample_;       // scratch
  std::vector<int> kept_;                 // scratch
  mutable std::vector<int> tris_;         // scratch of overlapIn
};

}  // namespace godhand
