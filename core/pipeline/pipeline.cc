#include "pipeline/pipeline.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <stdexcept>

#include "physics/physics_world.h"

namespace godhand {

namespace {
using Clock = std::chrono::steady_clock;
double usSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
}
}  // namespace

Pipeline::Pipeline(const Scene& scene, std::vector<const HandModel*> hands, PipelineParams params)
    : Pipeline(scene, std::move(hands), std::move(params), PhysicsParams{}) {}

Pipeline::Pipeline(const Scene& scene, std::vector<const HandModel*> hands, PipelineParams params,
                   const PhysicsParams& physics)
    : scene_(scene), params_(std::move(params)), models_(std::move(hands)) {
  params_.validate();
  params_.step.rows.dt = params_.step.dt;
  // The hands' solvers share nothing but the read-only scene (each has its own collision world,
  // stepper and scratch), so they may run at once; the resolver merges them after. Each solver
  // may spread its bodies over all the threads (PipelineParams::body_threads): a hand whose frame
  // is light (free, or untracked) leaves its core to the other hand's bodies. (Threads / hands,
  // i.e. one each on two cores, left the busy hand on one core: two hands on the bunny 263-267 Hz
  // against 300-349 Hz with body threads of each hand's own; on the default scene, where both
  // hands are busy, 784-822 against 736-792 Hz: oversubscribed, they cost each other a little.)
  // With two or more hands the bodies' jobs go through one JobShare instead (below): no hand has
  // threads of its own, a thread that is done with its hands helps the others.
  const int threads = params_.trace > 0 ? 1 : std::min(params_.threads, static_cast<int>(std::max<size_t>(1, models_.size())));
  params_.body_threads = params_.trace > 0 ? 1 : std::max(params_.body_threads, params_.threads);
  for (const HandModel* m : models_) {
    if (!m) throw std::invalid_argument("pipeline: null hand model");
    solvers_.push_back(std::make_unique<HandSolver>(scene, *m, params_));
  }
  resolver_ = std::make_unique<Resolver>(scene, models_, params_);
  scene_stage_ = std::make_unique<SceneStage>(scene, params_, physics);
  const SceneSnapshot& s0 = scene_stage_->initial();
  for (auto& s : solvers_) s->setScene(s0);
  resolver_->setScene(s0);
  proposals_.resize(models_.size());
  report_.hands.resize(models_.size());
  workers_ = std::make_unique<Workers>(std::max(1, threads));
  hand_us_.assign(models_.size(), 0.0);
  hand_weight_.assign(models_.size(), 0.0);
  hand_order_.assign(models_.size(), 0);
  solve_hand_ = [this](int h) {
    const size_t i = static_cast<size_t>(h);
    const Clock::time_point t0 = Clock::now();
    proposals_[i] = &solvers_[i]->step(*inputs_[i], frame_);
    hand_us_[i] = usSince(t0);
  };
  if (threads >= 2 && solvers_.size() >= 2) {
    // Each thread of the pool takes hands while any is left, then helps the hands still running
    // with their bodies' queries (JobShare): a light hand's core goes to the heavy hand's bodies
    // once it is done, and never competes with them before (each hand's own body threads did:
    // confidence2 over the bunny, see README).
    share_ = std::make_unique<JobShare>(static_cast<int>(solvers_.size()), threads);
    // (A one-body tool keeps its body on its own thread: useShare declines.)
    for (size_t h = 0; h < solvers_.size(); ++h) solvers_[h]->useShare(share_.get(), static_cast<int>(h));
    solve_hands_shared_ = [this](int, int thread) {
      const int n = static_cast<int>(solvers_.size());
      std::exception_ptr error;
      for (int next = next_hand_.fetch_add(1); next < n; next = next_hand_.fetch_add(1)) {
        const int h = hand_order_[static_cast<size_t>(next)];
        try {
          solvers_[static_cast<size_t>(h)]->setShareThread(thread);
          solve_hand_(h);
        } catch (...) {
          if (!error) error = std::current_exception();
        }
        hands_done_.fetch_add(1);
      }
      share_->help(thread, [this, n] { return hands_done_.load() >= n; });
      if (error) std::rethrow_exception(error);
    };
  }
}

Pipeline::~Pipeline() = default;

std::vector<ObjectCost> Pipeline::godCosts() const {
  std::vector<ObjectCost> sum(scene_.objects.size());
  auto add = [&sum](const CollisionWorld& w) {
    for (size_t o = 0; o < sum.size() && o < w.costs().size(); ++o) {
      sum[o].us += w.costs()[o].us;
      sum[o].queries += w.costs()[o].queries;
    }
  };
  for (const auto& s : solvers_) s->addCosts(&sum);
  add(resolver_->collision());
  return sum;
}

const FrameReport& Pipeline::step(const std::vector<HandInput>& inputs) {
  if (inputs.size() != solvers_.size()) throw std::invalid_argument("pipeline: one input per hand expected");
  const Clock::time_point t_frame = Clock::now();
  const std::uint64_t frame = ++counters_.frames;
  report_.times = PipelineTimes{};
  report_.contacts = 0;
  // solvers
  inputs_.resize(inputs.size());
  for (size_t h = 0; h < inputs.size(); ++h) inputs_[h] = &inputs[h];
  frame_ = frame;
  if (share_) {
    // The hand that took longest last frame, less the time its thread spent on another hand's
    // jobs, has its bodies' jobs taken first (JobShare::setWeight).
    // The hands are taken heaviest first: the calling thread takes the first at once, a pool
    // thread the next once it has woken, so the heavy hand's start does not wait for that
    // wake-up (measured on confidence2 over the bunny, medians: the heavy hand started 50 µs into
    // the frame, now 22; the pool thread sleeps between frames, 1.2-1.7 ms apart in the bench).
    // (Insertion sort: stable, ties in hand order, and no allocation.)
    for (size_t h = 0; h < solvers_.size(); ++h) {
      hand_weight_[h] = hand_us_[h] - share_->takeLent(static_cast<int>(h));
      share_->setWeight(static_cast<int>(h), hand_weight_[h]);
      size_t j = h;
      for (; j > 0 && hand_weight_[static_cast<size_t>(hand_order_[j - 1])] < hand_weight_[h]; --j) hand_order_[j] = hand_order_[j - 1];
      hand_order_[j] = static_cast<int>(h);
    }
    next_hand_.store(0);
    hands_done_.store(0);
    workers_->runSlots(share_->threads(), solve_hands_shared_);
  } else {
    workers_->run(static_cast<int>(solvers_.size()), solve_hand_);
  }
  // resolver
  resolver_->resolve(proposals_, frame);
  for (size_t h = 0; h < solvers_.size(); ++h) solvers_[h]->adopt(resolver_->result(static_cast<int>(h)));
  // scene
  const Clock::time_point t_scene = Clock::now();
  const SceneSnapshot& snap = scene_stage_->step(&resolver_->forces(), frame);
  for (auto& s : solvers_) s->setScene(snap);
  resolver_->setScene(snap);
  report_.times.scene_us = usSince(t_scene);
  report_.scene_pushouts = snap.pushouts;
  // report
  for (size_t h = 0; h < solvers_.size(); ++h) {
    const HandResult& r = resolver_->result(static_cast<int>(h));
    HandFrameReport& rep = report_.hands[h];
    rep = HandFrameReport{};
    rep.tracked = r.tracked;
    rep.started = r.started;
    rep.lifted_start = r.lifted_start;
    rep.diag = r.diag;
    rep.force_N = r.force_N;
    rep.loaded = r.loaded;
    report_.contacts += r.diag.contacts;
    report_.times.contacts_us += r.diag.times.contacts_us;
    report_.times.assembly_us += r.diag.times.assembly_us;
    report_.times.solve_us += r.diag.times.solve_us;
    report_.times.integrate_us += r.diag.times.integrate_us;
    report_.times.ccd_us += r.ccd_us + r.diag.times.ccd_us;
    report_.times.merge_us += r.merge_us;
  }
  // counters: the sums of the stages'
  PipelineCounters& c = counters_;
  c.clipped_steps = resolver_->counters().clipped_steps;
  c.started_inside = resolver_->counters().started_inside;
  c.forces_clamped = resolver_->counters().forces_clamped;
  c.scene_pushouts = scene_stage_->counters().scene_pushouts;
  c.pushout_unresolved = scene_stage_->counters().pushout_unresolved;
  c.pushout_restored = scene_stage_->counters().pushout_restored;
  c.lifted_starts = c.solver_failures = c.inexact_solves = c.rounds_shortened = c.rounds_kept = c.reacquisitions = c.reversed_rounds = c.hit_resolves = c.resolves_undone = 0;
  c.sweeps = c.sweep_iterations = c.sweeps_capped = c.per_body_clips = c.uniform_clips = c.sweeps_certified = c.held_rounds = 0;
  c.qp_tree = c.qp_general = 0;
  for (const auto& s : solvers_) {
    c.qp_tree += s->stepper().qpTreeSolves();
    c.qp_general += s->stepper().qpGeneralSolves();
    c.per_body_clips += s->counters().per_body_clips;
    c.uniform_clips += s->counters().uniform_clips;
    c.sweeps_certified += s->counters().sweeps_certified;
    c.held_rounds += s->counters().held_rounds;
    c.sweeps += s->counters().sweeps;
    c.sweep_iterations += s->counters().sweep_iterations;
    c.sweeps_capped += s->counters().sweeps_capped;
    c.lifted_starts += s->counters().lifted_starts;
    c.solver_failures += s->counters().solver_failures;
    c.inexact_solves += s->counters().inexact_solves;
    c.rounds_shortened += s->counters().rounds_shortened;
    c.rounds_kept += s->counters().rounds_kept;
    c.reacquisitions += s->counters().reacquisitions;
    c.reversed_rounds += s->counters().reversed_rounds;
    c.hit_resolves += s->counters().hit_resolves;
    c.resolves_undone += s->counters().resolves_undone;
  }
  report_.times.total_us = usSince(t_frame);
  return report_;
}

}  // namespace godhand
