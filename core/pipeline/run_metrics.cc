#include "pipeline/run_metrics.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <stdexcept>

#include "math/stats.h"

namespace godhand {

Spread spreadOf(const std::vector<const Sample*>& samples) {
  Spread s;
  std::vector<double> v;
  bool have_max = false;
  for (const Sample* x : samples) {
    if (x->empty()) continue;
    s.count += static_cast<std::size_t>(x->count());
    s.sampled = s.sampled || x->sampled();
    s.max = have_max ? std::max(s.max, x->max()) : x->max();
    have_max = true;
    v.insert(v.end(), x->values().begin(), x->values().end());
  }
  if (v.empty()) return s;
  if (!s.sampled) {
    s.median = percentile(v, 0.5);
    s.p95 = percentile(v, 0.95);
    return s;
  }
  // Sampled hands pooled: each kept value stands for count / kept values of its hand.
  std::vector<std::pair<double, double>> w;
  for (const Sample* x : samples)
    if (!x->empty()) {
      const double weight = static_cast<double>(x->count()) / static_cast<double>(x->values().size());
      for (const double value : x->values()) w.emplace_back(value, weight);
    }
  std::sort(w.begin(), w.end());
  double total = 0.0;
  for (const auto& e : w) total += e.second;
  auto at = [&](double p) {
    double cum = 0.0;
    for (const auto& e : w) {
      cum += e.second;
      if (cum >= p * total) return e.first;
    }
    return w.back().first;
  };
  s.median = at(0.5);
  s.p95 = at(0.95);
  return s;
}
namespace {
double maxBodyDistance(const std::vector<Pose>& a, const std::vector<Pose>& b) {
  double m = 0.0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) m = std::max(m, (a[i].p - b[i].p).norm());
  return m;
}
bool driven(const HandSample& s, size_t b) { return !s.has_target || s.has_target[b]; }

/// Jitter (run_metrics.h) of one hand's bodies at poses X, `prev` the poses of the frame before
/// (empty: none): `last` holds each body's motion of the frame before (NaN: none) and is updated.
/// Adds to *checked / *turned.
void countJitter(const std::vector<Pose>& X, const std::vector<Pose>& prev, std::vector<Vec3>* last,
                 std::uint64_t* checked, std::uint64_t* turned) {
  const Vec3 none = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  if (last->size() != X.size()) last->assign(X.size(), none);
  for (size_t b = 0; b < X.size(); ++b) {
    const Vec3 d = prev.size() == X.size() ? Vec3(X[b].p - prev[b].p) : none;
    const Vec3& e = (*last)[b];
    const double nd = d.norm(), ne = e.norm();
    if (nd > MetricThresholds::kJitterMove && ne > MetricThresholds::kJitterMove) {
      ++*checked;
      if (d.dot(e) < MetricThresholds::kJitterCos * nd * ne) ++*turned;
    } else if (d.allFinite() && e.allFinite()) {
      ++*checked;
    }
    (*last)[b] = d;
  }
}
}  // namespace

struct RunMetrics::Hand {
  HandSummary sum;
  const HandModel* model = nullptr;
  std::unique_ptr<HandSolver> twin;
  std::uint64_t frame = 0;
  // Per frame (gap: per body-frame touching), bounded over a long run (math/stats.h).
  Sample free_err, model_err, lag, gap;
  Sample lag_outside;  // the lag of the frames whose twin is outside every object
  /// (frame, God poses, twin poses) of the frames of the last kWindow that had both: a frame
  /// without them (a tracking dropout) does not end a window, its two ends are what is compared
  /// (as anyone comparing the --poses files of the run and its twin would).
  struct Seen {
    long long frame;
    std::vector<Pose> god, twin;
  };
  std::deque<Seen> window;
  std::vector<Pose> X_prev;  // God poses of the previous frame (empty: none)
  // Jitter: each body's motion of the frame before (NaN: none), God and twin, and the twin's
  // poses of the frame before.
  std::vector<Vec3> god_motion, twin_motion;
  std::vector<Pose> twin_prev;
};

RunMetrics::RunMetrics(const Scene& scene, std::vector<const HandModel*> models, std::vector<std::string> names,
                       const PipelineParams& params, bool twin)
    : params_(params) {
  (void)scene;
  if (models.size() != names.size()) throw std::invalid_argument("run metrics: one name per hand model");
  for (size_t h = 0; h < models.size(); ++h) {
    if (!models[h]) throw std::invalid_argument("run metrics: null hand model");
    auto hand = std::make_unique<Hand>();
    hand->sum.name = names[h];
    hand->model = models[h];
    if (twin) hand->twin = std::make_unique<HandSolver>(empty_, *models[h], params_);
    hands_.push_back(std::move(hand));
  }
}

RunMetrics::~RunMetrics() = default;

void RunMetrics::add(int h, const HandSample& s, const HandInput& input, const CollisionWorld& world) {
  const CollisionWorld::Untimed untimed(world);  // measuring is not the method's cost
  Hand& hand = *hands_.at(static_cast<size_t>(h));
  HandSummary& sum = hand.sum;
  const HandModel& m = *hand.model;
  const size_t n = m.bodies.size();
  ++hand.frame;
  ++sum.frames;
  if (s.tracked) ++sum.tracked;
  if (s.held) ++sum.held;
  if (s.tracked && !s.started) ++sum.never_started;
  if (s.clipped) ++sum.clipped_frames;
  if (s.clipped && s.toc < MetricThresholds::kTinyToc) ++sum.toc_below_1e3;
  sum.substeps += static_cast<std::uint64_t>(std::max(0, s.substeps));
  sum.substeps_max = std::max<std::uint64_t>(sum.substeps_max, static_cast<std::uint64_t>(std::max(0, s.substeps)));

  // The twin takes the same input whatever the God hand did with it.
  const std::vector<Pose>* twin = nullptr;
  if (hand.twin) {
    hand.twin->step(input, hand.frame);
    if (hand.twin->started()) twin = &hand.twin->stepper().poses();
  }
  if (twin && s.tracked) {
    countJitter(*twin, hand.twin_prev, &hand.twin_motion, &sum.twin_jitter_checked, &sum.twin_jitter_body_frames);
    hand.twin_prev = *twin;
  } else {
    hand.twin_prev.clear();
    hand.twin_motion.clear();
  }
  if (!s.started || !s.X) {
    hand.X_prev.clear();
    hand.god_motion.clear();
    return;
  }
  ++sum.started;
  const std::vector<Pose> X(s.X, s.X + n);
  double pen = 0.0;
  for (size_t b = 0; b < n; ++b) pen = std::max(pen, world.penetration(m.bodies[b].shape, X[b]));
  sum.penetration_max_m = std::max(sum.penetration_max_m, pen);
  for (size_t b = 0; b < n; ++b)  // the contact gap: touching the God side, how far from the true surface
    if (world.clearance(m.bodies[b].shape, X[b], MetricThresholds::kTouching) <= MetricThresholds::kTouching)
      hand.gap.add(
          std::min(world.referenceClearance(m.bodies[b].shape, X[b], MetricThresholds::kGapRange), MetricThresholds::kGapRange));
  sum.joint_gap_max_m = std::max(sum.joint_gap_max_m, s.joint_gap);

  const bool has_targets = s.tracked && s.targets;
  // The twin's distance to the targets: the model error (what the model cannot follow), also
  // the yardstick of "stuck" below.
  double model_err = 0.0;
  if (twin && has_targets)
    for (size_t b = 0; b < n; ++b)
      if (driven(s, b) && s.targets[b].p.allFinite()) model_err = std::max(model_err, ((*twin)[b].p - s.targets[b].p).norm());
  if (has_targets) {
    double to_target = 0.0;
    for (size_t b = 0; b < n; ++b)
      if (driven(s, b) && s.targets[b].p.allFinite()) to_target = std::max(to_target, (X[b].p - s.targets[b].p).norm());
    if (!s.loaded) hand.free_err.add(to_target);
    // Stuck: not moving, away from the targets (farther than the free twin, which is as near as
    // the model can come: what it cannot represent is model error, not a stuck hand), and
    // nothing in the way of going straight there.
    if (!s.held && !hand.X_prev.empty() && maxBodyDistance(X, hand.X_prev) < MetricThresholds::kGodStill &&
        to_target - model_err > MetricThresholds::kAwayFromTarget) {
      bool path_free = true;
      for (size_t b = 0; b < n && path_free; ++b) {
        if (!driven(s, b) || !isValidPose(s.targets[b], 1e-6)) continue;
        const geo::SweepResult r = world.sweep(m.bodies[b].shape, X[b], s.targets[b], params_.sweep);
        path_free = !r.hit && !r.started_inside && r.toc >= 1.0;
      }
      if (path_free) ++sum.stuck_frames;
    }
  }
  if (twin && has_targets) {
    double depth = 0.0;
    for (size_t b = 0; b < n; ++b) depth = std::max(depth, world.penetration(m.bodies[b].shape, (*twin)[b]));
    hand.model_err.add(model_err);
    const double e = maxBodyDistance(X, *twin) - depth;
    hand.lag.add(e);
    if (e > MetricThresholds::kLagAbove) ++sum.lag_above_5mm;
    if (!(depth > MetricThresholds::kTwinInside)) {
      hand.lag_outside.add(e);
      if (e > MetricThresholds::kLagAbove) ++sum.lag_above_5mm_twin_outside;
    }
  }
  if (twin) {
    const long long now = static_cast<long long>(hand.frame);
    while (!hand.window.empty() && hand.window.front().frame < now - MetricThresholds::kWindow) hand.window.pop_front();
    if (!hand.window.empty() && hand.window.front().frame == now - MetricThresholds::kWindow) {
      const Hand::Seen& a = hand.window.front();
      if (maxBodyDistance(*twin, a.twin) > MetricThresholds::kTwinMoves) {
        ++sum.moving_windows;
        if (maxBodyDistance(X, a.god) < MetricThresholds::kGodStill) ++sum.frozen_windows;
      }
    }
    hand.window.push_back(Hand::Seen{now, X, *twin});
  }
  if (s.tracked && !s.held) {
    countJitter(X, hand.X_prev, &hand.god_motion, &sum.jitter_checked, &sum.jitter_body_frames);
  } else {
    hand.god_motion.clear();
  }
  hand.X_prev = X;
}

RunSummary RunMetrics::summary() const {
  RunSummary out;
  std::vector<const Sample*> free_all, model_all, lag_all, gap_all, lag_outside_all;
  HandSummary& all = out.all;
  all.name = "all";
  for (const auto& hp : hands_) {
    const Hand& hand = *hp;
    HandSummary s = hand.sum;
    s.free_tracking_error_m = spreadOf({&hand.free_err});
    s.model_error_m = spreadOf({&hand.model_err});
    s.excess_lag_m = spreadOf({&hand.lag});
    s.excess_lag_twin_outside_m = spreadOf({&hand.lag_outside});
    s.contact_gap_m = spreadOf({&hand.gap});
    out.hands.push_back(s);
    free_all.push_back(&hand.free_err);
    model_all.push_back(&hand.model_err);
    lag_all.push_back(&hand.lag);
    lag_outside_all.push_back(&hand.lag_outside);
    gap_all.push_back(&hand.gap);
    all.frames += s.frames;
    all.tracked += s.tracked;
    all.started += s.started;
    all.held += s.held;
    all.never_started += s.never_started;
    all.penetration_max_m = std::max(all.penetration_max_m, s.penetration_max_m);
    all.joint_gap_max_m = std::max(all.joint_gap_max_m, s.joint_gap_max_m);
    all.lag_above_5mm += s.lag_above_5mm;
    all.lag_above_5mm_twin_outside += s.lag_above_5mm_twin_outside;
    all.moving_windows += s.moving_windows;
    all.frozen_windows += s.frozen_windows;
    all.stuck_frames += s.stuck_frames;
    all.jitter_checked += s.jitter_checked;
    all.jitter_body_frames += s.jitter_body_frames;
    all.twin_jitter_checked += s.twin_jitter_checked;
    all.twin_jitter_body_frames += s.twin_jitter_body_frames;
    all.clipped_frames += s.clipped_frames;
    all.toc_below_1e3 += s.toc_below_1e3;
    all.substeps += s.substeps;
    all.substeps_max = std::max(all.substeps_max, s.substeps_max);
    if (out.failure.empty() && s.tracked > 0) {
      if (s.started == 0)
        out.failure = "hand '" + s.name + "' never started (" + std::to_string(s.tracked) +
                      " tracked frames; every start pose was occupied: is the scene enclosing the tracking volume?)";
      else if (2 * (s.held + s.never_started) > s.tracked)
        out.failure = "hand '" + s.name + "' was held or not started in " + std::to_string(s.held + s.never_started) +
                      " of its " + std::to_string(s.tracked) + " tracked frames";
    }
  }
  // No hand tracked in any frame (a lab of one left cluster and a right-hand recording): nothing
  // was measured, which is no result. (One cluster of a two-hand lab idle under a one-hand
  // recording is a run of the other hand: its summary line says "not measured".)
  if (out.failure.empty() && !out.hands.empty() && all.tracked == 0) {
    std::string names;
    for (const HandSummary& s : out.hands) names += (names.empty() ? "'" : ", '") + s.name + "'";
    out.failure = "no hand was ever tracked (" + names + ": no frame of the source had a hand of their side; wrong side, hand map or recording?)";
  }
  all.free_tracking_error_m = spreadOf(free_all);
  all.model_error_m = spreadOf(model_all);
  all.excess_lag_m = spreadOf(lag_all);
  all.excess_lag_twin_outside_m = spreadOf(lag_outside_all);
  all.contact_gap_m = spreadOf(gap_all);
  return out;
}

ObjectShares objectShares(const Scene& scene, const std::vector<ObjectCost>& costs,
                          const std::vector<std::uint64_t>& awake_frames, std::uint64_t frames, double frames_us) {
  ObjectShares out;
  out.simulated = !awake_frames.empty();
  out.frames = frames;
  out.frames_us = frames_us;
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    ObjectShare sh;
    sh.id = scene.objects[o].id;
    sh.dynamic = scene.objects[o].mass > 0.0;
    if (o < costs.size()) {
      sh.god_us = costs[o].us;
      sh.god_queries = costs[o].queries;
    }
    sh.god_share = frames_us > 0.0 ? sh.god_us / frames_us : 0.0;
    if (o < awake_frames.size()) sh.awake_frames = awake_frames[o];
    out.god_us += sh.god_us;
    out.objects.push_back(sh);
  }
  return out;
}

std::string describe(const ObjectShares& s) {
  constexpr size_t kNamed = 4;  // the costliest objects by name, the rest together
  std::vector<size_t> order(s.objects.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return s.objects[a].god_us > s.objects[b].god_us; });
  const double per_frame = s.frames > 0 ? 1.0 / static_cast<double>(s.frames) : 0.0;
  char buf[256];
  std::string line = "God side by object (contacts, sweeps, distances, every thread's time summed; share of the frame "
                     "time):";
  size_t named = 0;  // the costliest queried objects
  while (named < order.size() && named < kNamed && s.objects[order[named]].god_queries > 0) ++named;
  if (named == 0) {
    std::snprintf(buf, sizeof buf, " no object queried (%zu objects)", order.size());
    line += buf;
  }
  for (size_t k = 0; k < named; ++k) {
    const ObjectShare& o = s.objects[order[k]];
    std::snprintf(buf, sizeof buf, "%s %s %.1f %% (%.1f us a frame, %llu queries)", k ? "," : "", o.id.c_str(),
                  100.0 * o.god_share, o.god_us * per_frame, static_cast<unsigned long long>(o.god_queries));
    line += buf;
  }
  if (named > 0 && order.size() > named) {
    double us = 0.0;
    std::uint64_t queries = 0;
    size_t never = 0;
    for (size_t k = named; k < order.size(); ++k) {
      us += s.objects[order[k]].god_us;
      queries += s.objects[order[k]].god_queries;
      never += s.objects[order[k]].god_queries == 0 ? 1 : 0;
    }
    std::snprintf(buf, sizeof buf, ", the other %zu objects %.1f %% together (%llu queries; %zu never queried)",
                  order.size() - named, s.frames_us > 0.0 ? 100.0 * us / s.frames_us : 0.0,
                  static_cast<unsigned long long>(queries), never);
    line += buf;
  }
  std::snprintf(buf, sizeof buf, "; all %.1f %%", s.frames_us > 0.0 ? 100.0 * s.god_us / s.frames_us : 0.0);
  line += buf;
  size_t dynamic = 0;
  std::uint64_t awake = 0;
  for (const ObjectShare& o : s.objects)
    if (o.dynamic) {
      ++dynamic;
      awake += o.awake_frames;
    }
  if (dynamic > 0 && !s.simulated) {
    line += ". Dynamic objects not simulated";
  } else if (dynamic > 0) {
    std::snprintf(buf, sizeof buf, ". Bullet: %zu dynamic objects awake in %llu of %llu object-frames (asleep: not integrated)",
                  dynamic, static_cast<unsigned long long>(awake), static_cast<unsigned long long>(dynamic * s.frames));
    line += buf;
  }
  return line;
}

}  // namespace godhand
