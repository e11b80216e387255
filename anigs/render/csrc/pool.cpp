// Parallel loops for the CPU rasterizer (included by raster.cpp): parallel_for hands out
// chunks of an index range to the threads, dynamically.
//
// Built with -fopenmp (the default) the loops use OpenMP: pip torch's bundled libgomp.so.1
// is shared with the kernel, so they run on torch's own worker threads. Without OpenMP
// (or with ANIGS_KERNEL_THREADS=pool) a small fork-join pool of std::threads does it:
// run(n, fn) calls fn on the calling thread and on up to n - 1 workers; workers spin for a
// few microseconds, then sleep, and the caller never waits for a worker that has not
// started (see Pool). If the pool is busy (another thread is rendering) the job runs on the
// calling thread alone, which gives the same results.
#include <algorithm>
#include <atomic>
#include <cstdlib>
#ifdef _OPENMP
#include <omp.h>
#else
#include <condition_variable>
#include <mutex>
#include <type_traits>
#include <thread>
#include <vector>
#include <unistd.h>
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define ANIGS_PAUSE() _mm_pause()
#else
#define ANIGS_PAUSE() std::this_thread::yield()
#endif
#endif  // !_OPENMP

namespace pool {

#ifndef _OPENMP
// Pause iterations before a waiting thread sleeps ($ANIGS_POOL_SPIN, for experiments).
inline int spin_count() {
  static const int n = [] {
    const char* e = std::getenv("ANIGS_POOL_SPIN");
    return e ? std::atoi(e) : 2000;
  }();
  return n;
}

typedef void (*JobFn)(void* ctx, int tid);

struct Pool {
  std::mutex busy;  // one job at a time
  std::mutex m;
  std::condition_variable cv_start, cv_done;
  std::atomic<unsigned> gen{0};   // job counter: a change wakes the workers
  std::atomic<bool> open{false};  // the current job still takes workers
  std::atomic<int> joined{0};     // workers inside the current job
  std::atomic<JobFn> fn{nullptr};
  std::atomic<void*> ctx{nullptr};
  std::atomic<int> participants{0};  // workers 1..participants-1 may join
  int nworkers = 0;  // threads started (tids 1..nworkers)
  pid_t pid = 0;

  // A worker joins a job only while it is open, and the caller closes it as soon as it has
  // finished its own share: a worker that the OS has not scheduled in time is never waited
  // for (with OpenMP's barrier, a descheduled team thread stalls every parallel region on a
  // busy machine).
  void worker(int tid, unsigned seen) {
    for (;;) {
      int k = 0;
      while (gen.load(std::memory_order_acquire) == seen && k < spin_count()) { ANIGS_PAUSE(); ++k; }
      if (gen.load(std::memory_order_acquire) == seen) {
        std::unique_lock<std::mutex> lk(m);
        cv_start.wait(lk, [&] { return gen.load(std::memory_order_acquire) != seen; });
      }
      seen = gen.load(std::memory_order_acquire);
      joined.fetch_add(1);
      if (open.load() && tid < participants.load()) fn.load()(ctx.load(), tid);
      if (joined.fetch_sub(1) == 1 && !open.load()) {
        std::lock_guard<std::mutex> lk(m);
        cv_done.notify_one();
      }
    }
  }

  void ensure(int n) {  // at least n - 1 workers; called before the job is posted
    const unsigned g = gen.load(std::memory_order_acquire);
    while (nworkers < n - 1) {
      const int tid = ++nworkers;
      std::thread([this, tid, g] { worker(tid, g); }).detach();
    }
  }

  // f must hand out its work dynamically (any subset of the workers may take part).
  void run(int n, JobFn f, void* c) {
    {
      std::lock_guard<std::mutex> lk(m);
      fn.store(f); ctx.store(c); participants.store(n);
      open.store(true);
      gen.fetch_add(1);
    }
    cv_start.notify_all();
    f(c, 0);
    open.store(false);  // no new joiners; wait for those inside
    int k = 0;
    while (joined.load() != 0 && k < spin_count()) { ANIGS_PAUSE(); ++k; }
    if (joined.load() != 0) {
      std::unique_lock<std::mutex> lk(m);
      cv_done.wait(lk, [&] { return joined.load() == 0; });
    }
  }
};

inline Pool* instance() {
  static std::mutex init;
  static Pool* p = nullptr;
  std::lock_guard<std::mutex> lk(init);
  if (p == nullptr || p->pid != getpid()) {  // a forked child has none of the parent's threads
    p = new Pool();  // never freed: detached workers may still reference it at exit
    p->pid = getpid();
  }
  return p;
}

template <class F> void trampoline(void* ctx, int tid) { (*static_cast<F*>(ctx))(tid); }

// fn(tid) for tid in [0, n).
template <class F> void run(int n, F&& fn) {
  if (n <= 1) {
    fn(0);
    return;
  }
  Pool* p = instance();
  if (!p->busy.try_lock()) {
    fn(0);
    return;
  }
  p->ensure(n);
  typedef typename std::remove_reference<F>::type FT;
  p->run(n, &trampoline<FT>, static_cast<void*>(&fn));
  p->busy.unlock();
}

#endif  // !_OPENMP

inline int max_threads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  const unsigned hc = std::thread::hardware_concurrency();
  return hc > 0 ? int(hc) : 1;
#endif
}

// body(begin, end) over [0, count) in chunks of `grain`, handed out dynamically (a thread
// that starts late just takes fewer chunks). Each index is processed exactly once, so
// results never depend on the thread count.
template <class F> void parallel_for(int count, int nthreads, int grain, F&& body) {
  if (count <= 0) return;
  grain = std::max(1, grain);
  const int nchunks = (count + grain - 1) / grain;
  const int n = std::max(1, std::min(nthreads, nchunks));
  if (n == 1) {
    body(0, count);
    return;
  }
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(n)
  for (int c = 0; c < nchunks; ++c) body(c * grain, std::min(count, (c + 1) * grain));
#else
  std::atomic<int> next{0};
  run(n, [&](int) {
    for (int c = next.fetch_add(1, std::memory_order_relaxed); c < nchunks;
         c = next.fetch_add(1, std::memory_order_relaxed))
      body(c * grain, std::min(count, (c + 1) * grain));
  });
#endif
}

}  // namespace pool
