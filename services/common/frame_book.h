// Samples of one topic kept per (ingest run, frame) and cluster, until a sample of another topic
// (the HandState solved from them) comes to be matched with its own: godhand-launch scores each
// HandState against its frame's HandTarget. Keyed by the run too (Stamp.run, the ingest's start
// time in ns): a restarted ingest numbers its frames from 1 again, and a state of its frame k
// matched with the old run's frame k would be scored against the wrong targets.
#pragma once

#include <cstdint>
#include <map>
#include <utility>
#include <vector>

namespace godhand {

template <class T>
class FrameBook {
 public:
  /// clusters: slots per frame; capacity: frames kept (the oldest go first: runs are start
  /// times, so an older run's frames are older).
  explicit FrameBook(size_t clusters, size_t capacity = 512) : clusters_(clusters), capacity_(capacity) {}

  /// Keeps `item` for (run, frame, cluster), replacing one kept there; a cluster beyond the
  /// book's is ignored (false).
  bool put(std::uint64_t run, std::uint64_t frame, size_t cluster, const T& item) {
    if (cluster >= clusters_) return false;
    Slots& s = book_[Key{run, frame}];
    if (s.have.empty()) {
      s.items.resize(clusters_);
      s.have.assign(clusters_, 0);
    }
    s.items[cluster] = item;
    s.have[cluster] = 1;
    while (book_.size() > capacity_) book_.erase(book_.begin());
    return true;
  }
  /// The item kept for (run, frame, cluster), or nullptr.
  const T* find(std::uint64_t run, std::uint64_t frame, size_t cluster) const {
    const auto it = book_.find(Key{run, frame});
    if (it == book_.end() || cluster >= clusters_ || !it->second.have[cluster]) return nullptr;
    return &it->second.items[cluster];
  }
  /// Every cluster's item is kept for (run, frame).
  bool complete(std::uint64_t run, std::uint64_t frame) const {
    const auto it = book_.find(Key{run, frame});
    if (it == book_.end()) return false;
    for (unsigned char h : it->second.have)
      if (!h) return false;
    return true;
  }
  /// Forgets (run, frame) and everything older (older runs included).
  void eraseThrough(std::uint64_t run, std::uint64_t frame) { book_.erase(book_.begin(), book_.upper_bound(Key{run, frame})); }
  size_t size() const { return book_.size(); }

 private:
  using Key = std::pair<std::uint64_t, std::uint64_t>;  // run, frame
  struct Slots {
    std::vector<T> items;
    std::vector<unsigned char> have;
  };
  size_t clusters_, capacity_;
  std::map<Key, Slots> book_;
};

}  // namespace godhand
