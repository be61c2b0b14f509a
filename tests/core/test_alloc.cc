// Zero-allocation guard for the warm step (STYLE habit 2, cluster_step.h: "Nothing is allocated
// once warm (same or fewer rows than seen before)").
//
// When GODHAND_WRAP_MALLOC is defined the executable is linked with
// -Wl,--wrap=malloc,calloc,realloc,aligned_alloc,posix_memalign: every call to those from the
// statically linked core (and Eigen inside it) lands in the __wrap_ functions below, and the
// global operator new / new[] (all overloads) are replaced here; both count while `g_armed` is
// set. Without it (sanitizer builds, whose runtime owns malloc) the test skips.
//
// On a failure the test prints the return address of the first counted allocation; resolve it
// with `addr2line -Cfie build/bin/godhand_alloc_test ADDRESS`, or run the test under gdb with
// `break __wrap_malloc if g_armed` (or on operator new) to see the whole stack.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <string>
#include <vector>

#include "common/files.h"
#include "model/hand_model.h"
#include "pipeline/collision_world.h"
#include "scene/mesh_io.h"
#include "scene/scene.h"
#include "step/cluster_step.h"

#ifdef GODHAND_WRAP_MALLOC

std::atomic<bool> g_armed{false};
std::atomic<long> g_allocations{0};
std::atomic<void*> g_first_caller{nullptr};

namespace {
inline void countAllocation(void* caller) {
  if (!g_armed.load(std::memory_order_relaxed)) return;
  if (g_allocations.fetch_add(1, std::memory_order_relaxed) == 0) g_first_caller.store(caller, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* __real_malloc(size_t n);
void* __real_calloc(size_t n, size_t size);
void* __real_realloc(void* p, size_t n);
void* __real_aligned_alloc(size_t alignment, size_t n);
int __real_posix_memalign(void** out, size_t alignment, size_t n);

void* __wrap_malloc(size_t n) {
  countAllocation(__builtin_return_address(0));
  return __real_malloc(n);
}
void* __wrap_calloc(size_t n, size_t size) {
  countAllocation(__builtin_return_address(0));
  return __real_calloc(n, size);
}
void* __wrap_realloc(void* p, size_t n) {
  countAllocation(__builtin_return_address(0));
  return __real_realloc(p, n);
}
void* __wrap_aligned_alloc(size_t alignment, size_t n) {
  countAllocation(__builtin_return_address(0));
  return __real_aligned_alloc(alignment, n);
}
int __wrap_posix_memalign(void** out, size_t alignment, size_t n) {
  countAllocation(__builtin_return_address(0));
  return __real_posix_memalign(out, alignment, n);
}
}  // extern "C"

namespace {
void* newImpl(std::size_t n, void* caller) {
  countAllocation(caller);
  void* p = __real_malloc(n ? n : 1);
  if (!p) throw std::bad_alloc();
  return p;
}
void* newAlignedImpl(std::size_t n, std::align_val_t al, void* caller) {
  countAllocation(caller);
  const std::size_t a = std::max(static_cast<std::size_t>(al), sizeof(void*));
  void* p = nullptr;
  if (__real_posix_memalign(&p, a, n ? n : 1) != 0) throw std::bad_alloc();
  return p;
}
}  // namespace

void* operator new(std::size_t n) { return newImpl(n, __builtin_return_address(0)); }
void* operator new[](std::size_t n) { return newImpl(n, __builtin_return_address(0)); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try { return newImpl(n, __builtin_return_address(0)); } catch (...) { return nullptr; }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  try { return newImpl(n, __builtin_return_address(0)); } catch (...) { return nullptr; }
}
void* operator new(std::size_t n, std::align_val_t al) { return newAlignedImpl(n, al, __builtin_return_address(0)); }
void* operator new[](std::size_t n, std::align_val_t al) { return newAlignedImpl(n, al, __builtin_return_address(0)); }
void* operator new(std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  try { return newAlignedImpl(n, al, __builtin_return_address(0)); } catch (...) { return nullptr; }
}
void* operator new[](std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  try { return newAlignedImpl(n, al, __builtin_return_address(0)); } catch (...) { return nullptr; }
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }

#endif  // GODHAND_WRAP_MALLOC

namespace godhand {
namespace {

#ifdef GODHAND_WRAP_MALLOC
/// Counts allocations between construction and stop().
class AllocationCounter {
 public:
  AllocationCounter() {
    g_allocations.store(0);
    g_first_caller.store(nullptr);
    g_armed.store(true);
  }
  ~AllocationCounter() { g_armed.store(false); }
  long stop() {
    g_armed.store(false);
    return g_allocations.load();
  }
  static void* firstCaller() { return g_first_caller.load(); }
};

TEST(StepAlloc, CounterSeesMallocAndNew) {
  AllocationCounter counter;
  void* volatile p = std::malloc(64);
  std::free(p);
  int* volatile q = new int[16];
  delete[] q;
  struct alignas(64) Wide { double v[8]; };
  Wide* volatile w = new Wide;
  delete w;
  std::vector<double>* volatile v = new std::vector<double>(100);
  delete v;
  EXPECT_GE(counter.stop(), 5);
}
#endif

const HandModel& hand16() {
  static const HandModel m = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
  return m;
}

/// A point on a body's underside at parameters s, t ∈ [-1, 1] (capsule: along its axis; box:
/// over its local −z face; sphere: the lowest point).
Vec3 underside(const Body& b, const Pose& X, double s, double t) {
  switch (b.shape.type) {
    case ShapeType::Capsule: return X * Vec3(0, 0, s * b.shape.half_length) - Vec3(0, 0, b.shape.radius);
    case ShapeType::Sphere: return X.p - Vec3(0, 0, b.shape.radius);
    case ShapeType::Box: {
      const Vec3 h = b.shape.half_extents;
      return X * Vec3(s * h.x(), t * h.y(), -h.z());
    }
  }
  return X.p;
}

/// The hand pressed into the table z = 0 with 64 contacts (4 per body), sliding in a circle while
/// its fingers curl; every buffer is sized before the measured steps, so update() allocates nothing.
struct Scenario {
  explicit Scenario(SolverKind kind) : stepper(hand16(), params(kind)) {
    const HandModel& m = hand16();
    rest = m.restPoses(Pose{});
    double low = 1e9;
    for (size_t b = 0; b < rest.size(); ++b) low = std::min(low, underside(m.bodies[b], rest[b], 0, 0).z());
    for (Pose& P : rest) P.p.z() += 0.001 - low;  // 1 mm above the table
    stepper.reset(rest);
    stepper.reserve(64);
    targets = rest;
    contacts.resize(128);
  }
  static StepParams params(SolverKind kind) {
    StepParams p;
    p.solver = kind;
    return p;
  }
  void update(int frame, int n) {
    const HandModel& m = hand16();
    const double a = 0.01 * frame;
    Pose X_M;  // rigid part: circle, 5 mm into the table
    X_M.p = Vec3(0.01 * std::cos(a) - 0.01, 0.01 * std::sin(a), -0.005);
    for (size_t b = 0; b < targets.size(); ++b) targets[b] = X_M * rest[b];
    const double curl = 0.4 * (0.5 - 0.5 * std::cos(0.7 * a));
    for (const Joint& j : m.joints) {
      const Pose& P = targets[static_cast<size_t>(j.parent)];
      const Quat q = P.q * j.X_PJ.q * Quat(Eigen::AngleAxisd(curl, Vec3::UnitX())) * j.X_CJ.q.conjugate();
      Pose& C = targets[static_cast<size_t>(j.child)];
      C.q = q.normalized();
      C.p = P * j.X_PJ.p - C.q * j.X_CJ.p;
    }
    const auto& X = stepper.poses();
    for (int i = 0; i < n; ++i) {
      const int b = i % 16, slot = (i / 16) % 4;
      const double s = -1.0 + 2.0 * slot / 3.0, t = (i / 16) % 2 ? 1.0 : -1.0;
      Contact& c = contacts[static_cast<size_t>(i)];
      c.body = b;
      c.p_W = underside(m.bodies[static_cast<size_t>(b)], X[static_cast<size_t>(b)], s, t);
      c.n_W = Vec3::UnitZ();
      c.distance = c.p_W.z();
      c.key = static_cast<std::uint64_t>(i) + 1;
      c.object = 0;
    }
  }
  const StepReport& step(int frame, int n) {
    update(frame, n);
    return stepper.step({targets.data(), nullptr, contacts.data(), n});
  }
  ClusterStepper stepper;
  std::vector<Pose> rest, targets;
  std::vector<Contact> contacts;
};

void expectNoAllocation(SolverKind kind, const char* name) {
#ifndef GODHAND_WRAP_MALLOC
  (void)kind;
  (void)name;
  GTEST_SKIP() << "built without GODHAND_WRAP_MALLOC (sanitizer build: the sanitizer owns malloc); "
                  "the zero-allocation guard runs in the normal build only";
#else
  Scenario sc(kind);
  int frame = 0;
  for (int i = 0; i < 10; ++i) sc.step(frame++, 64);  // warm
  int max_rows = 0, contact_rows = 0, failures = 0;
  long count = 0;
  {
    AllocationCounter counter;
    for (int i = 0; i < 100; ++i) {
      const StepReport& r = sc.step(frame++, i % 3 == 2 ? 40 : 64);  // same or fewer contacts
      max_rows = std::max(max_rows, r.rows);
      contact_rows = std::max(contact_rows, r.contact_rows);
      failures += (r.flags & (kFlagSolverFailed | kFlagStateKept)) != 0;
    }
    count = counter.stop();
  }
  std::printf("[figure] alloc_%s_allocations_in_100_warm_steps = %ld (max rows %d, contact rows %d)\n", name, count,
              max_rows, contact_rows);
  EXPECT_EQ(contact_rows, 64);
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(count, 0) << "first allocation called from " << AllocationCounter::firstCaller()
                      << " (addr2line -Cfie godhand_alloc_test ADDRESS)";
  // The hand really was in contact (the measured steps were not trivially contact-free).
  double lambda = 0.0;
  for (int i = 0; i < 64; ++i) lambda += sc.stepper.contactLambda(i);  // last step had 64
  EXPECT_GT(lambda, 0.0);
  // Control: more contacts than ever reserved must grow the buffers, and the counter sees it
  // (proves the wrapped core is what is being counted).
  sc.update(frame++, 128);
  AllocationCounter counter;
  sc.stepper.step({sc.targets.data(), nullptr, sc.contacts.data(), 128});
  EXPECT_GT(counter.stop(), 0) << "growing past the reserved contact count was not seen by the counter";
#endif
}

TEST(StepAlloc, WarmExactStepAllocatesNothing) { expectNoAllocation(SolverKind::Exact, "exact"); }
TEST(StepAlloc, WarmPgsStepAllocatesNothing) { expectNoAllocation(SolverKind::Pgs, "pgs"); }

// The contact queries of a hand that reaches an object for the first time, long after its
// collision world was built (a lab's hand moving from one part to the next): no allocation, the
// per-object hints included (they are a fixed table allocated with the world).
TEST(CollisionAlloc, FirstQueriesOfAnObjectAllocateNothing) {
#ifndef GODHAND_WRAP_MALLOC
  GTEST_SKIP() << "built without GODHAND_WRAP_MALLOC (sanitizer build)";
#else
  Scene scene;
  scene.name = "parts";
  for (int i = 0; i < 40; ++i) {  // more objects than hint slots: slots are shared
    SceneObject o;
    o.id = "part" + std::to_string(i);
    o.index = i;
    o.X_WO = Pose{Vec3(0.2 * i, 0, 0), Quat::Identity()};
    o.god = std::make_shared<geo::MeshBvh>(boxMesh(Vec3(0.05, 0.05, 0.05)));
    o.reference = o.god;
    o.physics.type = PhysicsShapeType::None;
    scene.objects.push_back(std::move(o));
  }
  CollisionWorld world(scene);
  Shape palm;
  palm.type = ShapeType::Box;
  palm.half_extents = Vec3(0.04, 0.045, 0.01);
  Shape finger;
  finger.type = ShapeType::Capsule;
  finger.radius = 0.008;
  finger.half_length = 0.015;
  std::vector<Contact> out;
  out.reserve(256);
  CollisionWorld::QueryStart start;
  // Warm: the first part only, every body index the hand has.
  auto touch = [&](int part, int* found) {
    for (int b = 0; b < 16; ++b) {
      out.clear();
      const Pose X{Vec3(0.2 * part + 0.01 * (b % 4), 0, 0.05 + 0.012 + 0.002), Quat::Identity()};
      *found += world.contacts(b == 0 ? palm : finger, X, b, 0.005, ContactParams{}, &out, &start);
    }
  };
  int warm_found = 0;
  for (int i = 0; i < 3; ++i) touch(0, &warm_found);
  int found = 0;
  long count = 0;
  {
    AllocationCounter counter;
    for (int part = 1; part < 40; ++part) touch(part, &found);  // each reached for the first time
    for (int part = 0; part < 40; ++part) touch(part, &found);  // and again (slots now shared)
    count = counter.stop();
  }
  std::printf("[figure] collision_first_touch_allocations = %ld (%d contacts found on 79 part visits)\n", count, found);
  EXPECT_GT(warm_found, 0);
  EXPECT_GT(found, 79 * 16) << "every visit touched its part";
  EXPECT_EQ(count, 0) << "first allocation called from " << AllocationCounter::firstCaller()
                      << " (addr2line -Cfie godhand_alloc_test ADDRESS)";
#endif
}

}  // namespace
}  // namespace godhand

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
