// planning/pthread_once.cc replaces glibc's pthread_once (CGAL's lazy kernel calls it once per exact evaluation):
// it must be the one in use and keep the contract: the initialiser runs exactly once however many threads race,
// waiters return only after it finished (and see what it wrote), and one that throws leaves the control to be run
// again.

#include <gtest/gtest.h>
#include <pthread.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace {

int g_runs = 0;
void CountRun() { ++g_runs; }

TEST(PthreadOnce, IsViscosAndRunsOnce) {
  pthread_once_t control = PTHREAD_ONCE_INIT;
  ASSERT_EQ(pthread_once(&control, CountRun), 0);
  ASSERT_EQ(pthread_once(&control, CountRun), 0);
  EXPECT_EQ(g_runs, 1);
  EXPECT_EQ(control, 3) << "glibc's pthread_once is in use (its done state is 2), not planning/pthread_once.cc";
}

TEST(PthreadOnce, RacingThreadsRunEachInitialiserOnce) {
  constexpr int kFlags = 2000, kThreads = 8;
  std::vector<std::once_flag> flags(kFlags);
  std::vector<std::atomic<int>> runs(kFlags);
  std::vector<int> written(kFlags, 0);
  std::atomic<int> wrong{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      for (int k = 0; k < kFlags; ++k) {
        const int i = (k * 7 + t * 131) % kFlags;  // the threads meet on different flags at different times
        std::call_once(flags[i], [&] {
          runs[i].fetch_add(1);
          written[i] = i + 1;  // plain write: the waiters' read is ordered by the once
        });
        if (written[i] != i + 1) wrong.fetch_add(1);
      }
    });
  }
  for (auto& th : threads) th.join();
  for (int i = 0; i < kFlags; ++i) ASSERT_EQ(runs[i].load(), 1) << i;
  EXPECT_EQ(wrong.load(), 0);
}

TEST(PthreadOnce, WaitersReturnOnlyAfterASlowInitialiser) {
  std::once_flag flag;
  std::atomic<bool> finished{false};
  std::atomic<int> early{0};
  std::thread first([&] {
    std::call_once(flag, [&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      finished = true;
    });
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::vector<std::thread> waiters;
  for (int t = 0; t < 4; ++t) {
    waiters.emplace_back([&] {
      std::call_once(flag, [&] { early.fetch_add(100); });  // must not run: the first one is running
      if (!finished) early.fetch_add(1);
    });
  }
  first.join();
  for (auto& th : waiters) th.join();
  EXPECT_EQ(early.load(), 0);
}

TEST(PthreadOnce, AnInitialiserThatThrowsIsRunAgain) {
  std::once_flag flag;
  int attempts = 0;
  EXPECT_THROW(std::call_once(flag,
                              [&] {
                                ++attempts;
                                throw std::runtime_error("first attempt fails");
                              }),
               std::runtime_error);
  std::call_once(flag, [&] { ++attempts; });
  std::call_once(flag, [&] { ++attempts; });
  EXPECT_EQ(attempts, 2);
}

}  // namespace
