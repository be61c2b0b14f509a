#include "runtime/live_merge.h"

#include <algorithm>

namespace godhand::svc {

LiveMerge::LiveMerge(size_t clusters, double period_s, double merge_wait, double stale_after_s, Clock::time_point now)
    : C_(clusters),
      period_(period_s),
      merge_wait_(merge_wait),
      stale_after_(stale_after_s),
      have_(clusters, 0),
      frame_(clusters, 0),
      done_h_(clusters, 0),
      last_in_(clusters),
      last_publish_(now) {}

LiveMerge::Offer LiveMerge::offer(size_t h, std::uint64_t run, std::uint64_t frame, std::int64_t source_ns, Clock::time_point now) {
  Offer result = Offer::Accepted;
  // Nothing of cluster h accepted for stale_after while its samples keep coming: what comes is
  // followed again. (A sample whose frame number or source time is far ahead, e.g. a hostile one,
  // would otherwise make every later sample of the real run late, for good.) For another run,
  // the whole merge must have been idle that long: a slow cluster's leftover of the old run (its
  // solver still busy with an old target when the ingest restarted) is quiet itself, but must
  // not take the merge back from the new run the other clusters deliver.
  const bool quiet = last_in_[h] == Clock::time_point{} || now - last_in_[h] >= seconds(stale_after_);
  const bool idle = last_accept_ == Clock::time_point{} || now - last_accept_ >= seconds(stale_after_);
  if (run != run_) {
    if (run_ != 0 && !idle) {
      // A straggler of an old run; or a new run whose source time is ahead of the current run's
      // by more than the time since the current run's newest sample came (plus clock skew): not
      // a restarted ingest's.
      const double since = std::chrono::duration<double>(now - last_accept_).count();
      if (source_ns < run_source_ns_ ||
          static_cast<double>(source_ns) - static_cast<double>(run_source_ns_) > (since + kRunSkew_s) * 1e9)
        return Offer::Late;
    }
    run_ = run;
    run_source_ns_ = source_ns;
    std::fill(done_h_.begin(), done_h_.end(), 0);
    std::fill(have_.begin(), have_.end(), 0);
    result = Offer::NewRun;
  } else if (frame <= done_h_[h]) {
    if (!quiet) return Offer::Late;
    done_h_[h] = 0;  // the book of this cluster was ahead of what comes: start it again
    ++recoveries_;
  }
  run_source_ns_ = std::max(run_source_ns_, source_ns);
  last_accept_ = now;
  if (have_[h]) result = Offer::Superseded;
  bool any = false;
  for (unsigned char x : have_) any = any || x;
  if (!any) first_pending_ = now;
  have_[h] = 1;
  frame_[h] = frame;
  last_in_[h] = now;
  return result;
}

LiveMerge::Decision LiveMerge::decide(bool have_scene, Clock::time_point now) const {
  Decision d;
  bool any = false, ready = true;
  for (size_t h = 0; h < C_; ++h) {
    any = any || have_[h];
    // A cluster that has gone quiet is not waited for.
    const bool alive = last_in_[h] != Clock::time_point{} && now - last_in_[h] < seconds(stale_after_);
    if (alive && !have_[h]) ready = false;
  }
  if (!have_scene || !any) {
    if (have_scene && now - last_publish_ > seconds(stale_after_)) {
      d.kind = Decision::Republish;
      d.frame = done_;
    } else {
      d.until = now + std::chrono::milliseconds(50);
    }
    return d;
  }
  const Clock::time_point merge_until = first_pending_ + seconds(merge_wait_ * period_);
  if (!ready && now < merge_until) {
    d.until = merge_until;
    return d;
  }
  d.kind = Decision::Resolve;
  for (size_t h = 0; h < C_; ++h)
    if (have_[h]) d.frame = std::max(d.frame, frame_[h]);
  return d;
}

void LiveMerge::published(const Decision& d, Clock::time_point now) {
  if (d.kind == Decision::Wait) return;
  last_publish_ = now;
  done_ = std::max(done_, d.frame);
  if (d.kind != Decision::Resolve) return;
  for (size_t h = 0; h < C_; ++h)
    if (have_[h]) done_h_[h] = frame_[h];
  std::fill(have_.begin(), have_.end(), 0);
}

}  // namespace godhand::svc
