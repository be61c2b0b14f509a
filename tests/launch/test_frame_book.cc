// godhand-launch's matching of HandStates with their HandTargets (common/frame_book.h): kept per
// (ingest run, frame) and cluster. Oracle: small explicit histories worked out by hand.
#include <gtest/gtest.h>

#include <string>

#include "common/frame_book.h"

using namespace godhand;

TEST(FrameBook, ARestartedIngestsFrameIsNotTheOldRunsFrame) {
  FrameBook<std::string> book(2);
  const std::uint64_t old_run = 1000, new_run = 2000;  // runs are start times: the newer is larger
  book.put(old_run, 5, 0, "old right 5");
  book.put(old_run, 5, 1, "old left 5");
  // The ingest restarts and numbers its frames from 1 again: its frame 5 is not there yet.
  EXPECT_EQ(book.find(new_run, 5, 0), nullptr);
  EXPECT_FALSE(book.complete(new_run, 5));
  book.put(new_run, 5, 0, "new right 5");
  ASSERT_NE(book.find(new_run, 5, 0), nullptr);
  EXPECT_EQ(*book.find(new_run, 5, 0), "new right 5");
  EXPECT_EQ(*book.find(old_run, 5, 0), "old right 5");  // the old run's own is still its own
  EXPECT_FALSE(book.complete(new_run, 5));               // the left hand's has not come
  EXPECT_TRUE(book.complete(old_run, 5));
}

TEST(FrameBook, ClustersBeyondTheLabsAreIgnoredAndSlotsReplaced) {
  FrameBook<int> book(2);
  EXPECT_FALSE(book.put(7, 1, 2, 42));  // cluster 2 of a 2-cluster lab
  EXPECT_EQ(book.size(), 0u);
  EXPECT_EQ(book.find(7, 1, 2), nullptr);
  EXPECT_TRUE(book.put(7, 1, 1, 1));
  EXPECT_TRUE(book.put(7, 1, 1, 2));  // a re-sent sample replaces the one kept
  EXPECT_EQ(*book.find(7, 1, 1), 2);
  EXPECT_EQ(book.find(7, 1, 0), nullptr);  // an empty slot is not a sample
}

TEST(FrameBook, EraseThroughForgetsThatFrameAndEverythingOlder) {
  FrameBook<int> book(1);
  for (std::uint64_t f = 1; f <= 4; ++f) book.put(10, f, 0, static_cast<int>(f));
  for (std::uint64_t f = 1; f <= 2; ++f) book.put(20, f, 0, static_cast<int>(100 + f));
  book.eraseThrough(20, 1);  // the older run's frames 1-4 and the newer run's frame 1
  EXPECT_EQ(book.size(), 1u);
  EXPECT_EQ(book.find(10, 4, 0), nullptr);
  EXPECT_EQ(book.find(20, 1, 0), nullptr);
  ASSERT_NE(book.find(20, 2, 0), nullptr);
  EXPECT_EQ(*book.find(20, 2, 0), 102);
}

TEST(FrameBook, CapacityDropsTheOldestFrames) {
  FrameBook<int> book(1, 3);
  book.put(2, 9, 0, 0);   // newer run, sorts after every frame of run 1
  for (std::uint64_t f = 1; f <= 4; ++f) book.put(1, f, 0, static_cast<int>(f));
  EXPECT_EQ(book.size(), 3u);
  EXPECT_EQ(book.find(1, 1, 0), nullptr);
  EXPECT_EQ(book.find(1, 2, 0), nullptr);
  EXPECT_NE(book.find(1, 3, 0), nullptr);
  EXPECT_NE(book.find(1, 4, 0), nullptr);
  EXPECT_NE(book.find(2, 9, 0), nullptr);
}
