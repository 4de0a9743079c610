// SPDX-License-Identifier: Apache-2.0
// DistributedFor over a group of three "processes" run as threads that exchange through memory
// (the MPI transport itself is exercised by tests/cli_dmf_mpi_test under mpirun).
#include "thinslab/core/process_group.h"

#include <gtest/gtest.h>

#include <condition_variable>
#include <mutex>
#include <thread>

namespace thinslab {
namespace {

// An allgather for `size` threads: each deposits its bytes and waits for the others.
class MemoryExchange {
 public:
  explicit MemoryExchange(int size) : size_(size), slots_(size) {}
  Status Exchange(int rank, const std::string& mine, std::vector<std::string>* all) {
    std::unique_lock<std::mutex> lock(mutex_);
    const int round = round_;
    slots_[rank] = mine;
    if (++arrived_ == size_) {
      result_ = slots_;
      arrived_ = 0;
      ++round_;
      cv_.notify_all();
    } else {
      cv_.wait(lock, [&] { return round_ != round; });
    }
    *all = result_;
    return Status::Ok();
  }

 private:
  int size_;
  std::vector<std::string> slots_, result_;
  int arrived_ = 0, round_ = 0;
  std::mutex mutex_;
  std::condition_variable cv_;
};

// Squares of 0..n-1 on every process, each computing its share; `fail_rank` fails its compute in
// the second chunk.
void RunGroup(int size, int n, int chunk, int fail_rank, std::vector<std::vector<long>>* results,
              std::vector<Status>* statuses, std::vector<std::vector<int>>* computed) {
  MemoryExchange exchange(size);
  results->assign(size, std::vector<long>(n, -1));
  statuses->assign(size, Status::Ok());
  computed->assign(size, {});
  std::vector<std::thread> threads;
  for (int r = 0; r < size; ++r) {
    threads.emplace_back([&, r] {
      ProcessGroup group(r, size, [&, r](const std::string& mine, std::vector<std::string>* all) {
        return exchange.Exchange(r, mine, all);
      });
      std::vector<long>& values = (*results)[r];
      int chunks = 0;
      DistributedLoop loop;
      loop.compute = [&](int begin, int end) {
        if (r == fail_rank && chunks == 1) return Status::Error("frame 7 is truncated");
        for (int i = begin; i < end; ++i) {
          values[i] = static_cast<long>(i) * i;
          (*computed)[r].push_back(i);
        }
        return Status::Ok();
      };
      loop.pack = [&](int i, ByteWriter* out) { out->Put(values[i]); };
      loop.unpack = [&](int i, ByteReader* in) { return in->Get(&values[i]); };
      loop.chunk_done = [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
          if (values[i] != static_cast<long>(i) * i) return Status::Error("item " + std::to_string(i) + " unknown");
        }
        ++chunks;
        return Status::Ok();
      };
      (*statuses)[r] = DistributedFor(group, n, chunk, "squares", loop);
    });
  }
  for (auto& t : threads) t.join();
}

TEST(DistributedFor, EveryProcessEndsWithEveryItemEachComputedOnce) {
  std::vector<std::vector<long>> results;
  std::vector<Status> statuses;
  std::vector<std::vector<int>> computed;
  RunGroup(3, 100, 16, -1, &results, &statuses, &computed);
  std::vector<int> times(100, 0);
  for (int r = 0; r < 3; ++r) {
    EXPECT_TRUE(statuses[r].ok()) << statuses[r].message();
    for (int i = 0; i < 100; ++i) EXPECT_EQ(results[r][i], static_cast<long>(i) * i) << "rank " << r << " item " << i;
    for (int i : computed[r]) ++times[i];
    // A third of each chunk, +-1: 6 chunks of 16 (5 or 6 items each) and one of 4 (1 or 2).
    EXPECT_GE(computed[r].size(), 31u);
    EXPECT_LE(computed[r].size(), 38u);
  }
  for (int i = 0; i < 100; ++i) EXPECT_EQ(times[i], 1) << "item " << i;
}

TEST(DistributedFor, OneProcessesErrorEndsEveryProcessWithIt) {
  std::vector<std::vector<long>> results;
  std::vector<Status> statuses;
  std::vector<std::vector<int>> computed;
  RunGroup(3, 100, 16, 1, &results, &statuses, &computed);
  for (int r = 0; r < 3; ++r) {
    ASSERT_FALSE(statuses[r].ok()) << "rank " << r;
    EXPECT_EQ(statuses[r].message(), "process 1 of 3: frame 7 is truncated") << "rank " << r;
  }
}

TEST(DistributedFor, AloneComputesEveryChunkAndPacksNothing) {
  ProcessGroup alone;
  std::vector<int> seen;
  DistributedLoop loop;
  loop.compute = [&](int begin, int end) {
    for (int i = begin; i < end; ++i) seen.push_back(i);
    return Status::Ok();
  };
  loop.pack = [](int, ByteWriter*) { ADD_FAILURE() << "packed alone"; };
  loop.unpack = [](int, ByteReader*) { return false; };
  ASSERT_TRUE(DistributedFor(alone, 10, 4, "alone", loop).ok());
  EXPECT_EQ(seen.size(), 10u);
  EXPECT_EQ(ShareBegin(0, 10, 0, 3), 0);
  EXPECT_EQ(ShareBegin(0, 10, 3, 3), 10);
}

TEST(ByteBuffer, ReadsBackWhatWasWrittenAndRefusesAShortMessage) {
  ByteWriter w;
  w.Put<int>(7);
  w.PutVector(std::vector<double>{1.5, -2});
  w.PutString("dot");
  w.PutVector(std::vector<float>());  // Empty: no bytes copied from or into a null pointer.
  const std::string bytes = w.Release();
  ByteReader r(bytes);
  int i = 0;
  std::vector<double> v;
  std::string s;
  std::vector<float> empty{1};
  ASSERT_TRUE(r.Get(&i) && r.GetVector(&v) && r.GetString(&s) && r.GetVector(&empty));
  EXPECT_TRUE(empty.empty());
  EXPECT_EQ(i, 7);
  EXPECT_EQ(v, (std::vector<double>{1.5, -2}));
  EXPECT_EQ(s, "dot");
  EXPECT_TRUE(r.at_end());
  const std::string cut = bytes.substr(0, 10);
  ByteReader short_reader(cut);
  EXPECT_TRUE(short_reader.Get(&i));
  EXPECT_FALSE(short_reader.GetVector(&v));
}

}  // namespace
}  // namespace thinslab
