// The parallel seam: every loop shape the grid cycle uses, and the only
// place that knows the threading backend (OpenMP). A kernel says what it
// does for one particle, one node or one block; these say how the work is
// spread. Another backend (Kokkos, CUDA, SYCL) replaces this file's bodies
// (docs/design-decisions.md, "The parallel seam").
//
// Inside the loops: no strings, locks or allocation. A failure is recorded
// in a FirstFailure (one plain record per thread) and turned into a message
// once the loop is over.
#pragma once

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace talus::par {

inline int max_threads() {
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

// Processors the process may run on (OpenMP reads its affinity mask).
inline int processors() {
#ifdef _OPENMP
    return omp_get_num_procs();
#else
    return 1;
#endif
}

inline int thread_index() {
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

// Parallel regions started so far (each ends in a barrier where every
// thread waits for the slowest): counted by the loop shapes below, from the
// thread that starts them, for talus_bench's report.
inline long &regions() {
    static long count = 0;
    return count;
}

inline void set_threads(int n) {
#ifdef _OPENMP
    if (n > 0) omp_set_num_threads(n);
#else
    (void)n;
#endif
}

// f(i) for i in [0, n): particles of a set or nodes of the grid, in equal
// static chunks (each thread touches the same memory every step).
template <class F>
void for_each(std::size_t n, F &&f) {
    const std::ptrdiff_t N = static_cast<std::ptrdiff_t>(n);
    ++regions();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < N; ++i)
        f(static_cast<std::size_t>(i));
}

// Items [0, count) dealt out in T contiguous shares, one a thread: each
// thread takes its own share's items from the front, then, when it has
// none left, the others' from their backs. Dynamic, as a shared counter
// is, but each thread comes back to the same items (the same particles and
// nodes) step after step, phase after phase, as far as the work is even.
// Where the two cores sit on different dies, each with its own last-level
// cache, a store takes long to reach the other core (`talus_bench --case
// core_to_core`), and a counter that hands consecutive chunks to alternate
// threads sends half of the lines one thread wrote to the other's cache in
// the next phase (docs/performance.md, "The two cores share no cache";
// bench/results/2026-11-29-shares-no-shared-cache-epyc-zen5.md).
class Shares {
  public:
    Shares(std::uint64_t count, int threads)
        : share_(std::make_unique<Share[]>(static_cast<std::size_t>(threads))), T_(threads) {
        // A share is (first, end) in one word, so that its owner's front
        // and the others' back are taken by one compare-and-swap.
        assert(count < (std::uint64_t{1} << 32));
        const auto n = static_cast<std::uint64_t>(threads);
        for (std::uint64_t u = 0; u < n; ++u)
            share_[u].v.store(count * u / n << 32 | count * (u + 1) / n, std::memory_order_relaxed);
    }
    // g(item) for every item, on thread t of any team (of at most T
    // threads: the shares of threads the team lacks are taken by the
    // others). The caller's region ends in a barrier after the last item.
    template <class G>
    void run(int t, G &&g) {
        take(share_[static_cast<std::size_t>(t)].v, g, true);
        for (int k = 1; k < T_; ++k)
            take(share_[static_cast<std::size_t>((t + k) % T_)].v, g, false);
    }

  private:
    template <class G>
    static void take(std::atomic<std::uint64_t> &share, G &g, bool front) {
        std::uint64_t w = share.load(std::memory_order_relaxed);
        for (;;) {
            const std::uint64_t first = w >> 32, end = w & 0xffffffffu;
            if (first >= end) return;
            const std::uint64_t item = front ? first : end - 1;
            const std::uint64_t rest = front ? (first + 1) << 32 | end : first << 32 | (end - 1);
            if (share.compare_exchange_weak(w, rest, std::memory_order_relaxed)) {
                g(item);
                w = share.load(std::memory_order_relaxed);
            }
        }
    }
    // A line each: the owners' updates do not pass a line between cores.
    struct alignas(64) Share {
        std::atomic<std::uint64_t> v;
    };
    std::unique_ptr<Share[]> share_;
    int T_;
};

// f(b) for blocks b in [0, n_blocks) of uneven cost (material batches: a
// plastic block costs more than an elastic one), dealt out dynamically in
// shares (Shares), so that a thread comes back to the blocks whose
// particles it moved in the pass before.
template <class F>
void for_each_block(std::size_t n_blocks, F &&f) {
    ++regions();
    Shares shares(static_cast<std::uint64_t>(n_blocks), max_threads());
#pragma omp parallel
    shares.run(thread_index(), [&](std::uint64_t b) { f(static_cast<std::size_t>(b)); });
}

// f(begin, end) for consecutive chunks of [0, n): for kernels that run a
// block of particles per call (one indirect call per chunk, not per
// particle). In equal static shares, or dealt out dynamically (Shares)
// when chunks cost unevenly (a G2P with the material update fused in: a
// plastic chunk costs more than an elastic one). Every chunk but the last
// has `chunk` elements, so each starts at a multiple of it.
enum class Schedule { equal_shares, dynamic };
inline constexpr std::size_t kDefaultChunk = 512;
template <class F>
void for_each_chunk(std::size_t n, F &&f, Schedule schedule = Schedule::equal_shares,
                    std::size_t chunk = kDefaultChunk) {
    const std::size_t kChunk = std::max<std::size_t>(1, chunk);
    const std::ptrdiff_t chunks = static_cast<std::ptrdiff_t>((n + kChunk - 1) / kChunk);
    if (schedule == Schedule::dynamic) {
        for_each_block(static_cast<std::size_t>(chunks), [&](std::size_t c) {
            const std::size_t begin = c * kChunk;
            f(begin, std::min(n, begin + kChunk));
        });
        return;
    }
    ++regions();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t c = 0; c < chunks; ++c) {
        const std::size_t begin = static_cast<std::size_t>(c) * kChunk;
        f(begin, std::min(n, begin + kChunk));
    }
}

// f(k) for a few large tasks k in [0, n_tasks) that the caller lists
// largest first (the columns of a particle set in its re-sort), handed
// out one at a time in that order: the longest go first, and the short
// ones fill in at the end.
template <class F>
void for_each_task(std::size_t n_tasks, F &&f) {
    const std::ptrdiff_t N = static_cast<std::ptrdiff_t>(n_tasks);
    ++regions();
#pragma omp parallel for schedule(dynamic, 1)
    for (std::ptrdiff_t k = 0; k < N; ++k)
        f(static_cast<std::size_t>(k));
}

// f(slab) for every slab, in two colours: the even slabs (colour 0), then
// the odd ones (colour 1). Slabs of one colour run concurrently and must
// not write the same memory (the caller's slabs are wide enough that every
// other one is apart, see Ordering); an odd slab writes memory its two even
// neighbours write, and runs once both are done.
//
// One region, not one per colour: a thread takes odd slabs once every even
// one is taken, and waits only for an odd slab's two neighbours, not for
// every even slab. With a barrier between the colours, a colour whose
// slabs do not divide evenly among the threads kept one idle at its end
// (the 3D benchmark block: 7 and 6 slabs, 2 threads). Each colour is dealt
// out in shares (Shares), so a thread scatters the same stretch of the
// grid every step, the stretch whose particles it moves in the fused G2P
// (the particles are stored slab by slab) and, where the slabs run across
// the last axis (Ordering's choice wherever it has 8 slabs), whose nodes
// it updates (the grid update shares out rows, in the last axis's order).
// Each node still gets its even slab's contributions before its
// odd slab's, and each slab's in its particles' order, so the sums have
// the same bits whatever the thread count. No wait can block forever: an
// odd slab waits on even ones, which were all taken before it by threads
// that wait on nothing.
template <class F>
void for_each_slab_by_colour(int n_slabs, F &&f) {
    if (n_slabs <= 0) return;
    const int n_even = (n_slabs + 1) / 2;
    // One small allocation a pass (none inside the loop); all false.
    const auto done = std::make_unique<std::atomic<bool>[]>(static_cast<std::size_t>(n_slabs));
    auto finished = [&](int slab) {
        return slab >= n_slabs ||
               done[static_cast<std::size_t>(slab)].load(std::memory_order_acquire);
    };
    Shares even(static_cast<std::uint64_t>(n_even), max_threads()),
        odd(static_cast<std::uint64_t>(n_slabs - n_even), max_threads());
    ++regions();
#pragma omp parallel
    {
        const int t = thread_index();
        even.run(t, [&](std::uint64_t k) {
            const int slab = 2 * static_cast<int>(k);
            f(slab);
            done[static_cast<std::size_t>(slab)].store(true, std::memory_order_release);
        });
        odd.run(t, [&](std::uint64_t k) {
            const int slab = 2 * static_cast<int>(k) + 1;
            for (int spins = 0; !(finished(slab - 1) && finished(slab + 1)); ++spins) {
                if (spins < 4096) {
#if defined(__x86_64__) || defined(__i386__)
                    __builtin_ia32_pause();
#endif
                } else {
                    std::this_thread::yield();
                }
            }
            f(slab);
            done[static_cast<std::size_t>(slab)].store(true, std::memory_order_release);
        });
    }
}

// The indices a partial of reduce() covers.
inline constexpr std::size_t kReduceChunk = 4096;

// f(i, partial) for i in [0, n), into one partial result R (default-
// constructed) per chunk of kReduceChunk consecutive indices, merged after
// the loop by R::merge(const R &) in chunk order (a partial may rely on it
// to see what happens at the boundaries between ranges). The chunks depend
// on n alone, so a floating-point sum rounds the same whatever the thread
// count: per-thread partials made the stages' kinetic energy ratio differ
// in its last bits between one and two threads, which could move a stage's
// end by a step in a run whose thread count changes, or on restart.
template <class R, class F>
R reduce(std::size_t n, F &&f) {
    const std::size_t chunks = (n + kReduceChunk - 1) / kReduceChunk;
    std::vector<R> partial(chunks);
    const std::ptrdiff_t N = static_cast<std::ptrdiff_t>(chunks);
    ++regions();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t c = 0; c < N; ++c) {
        // A local partial (registers, once the loop body is inlined), stored
        // once at the end.
        R mine{};
        const std::size_t begin = static_cast<std::size_t>(c) * kReduceChunk;
        const std::size_t end = std::min(n, begin + kReduceChunk);
        for (std::size_t i = begin; i < end; ++i)
            f(i, mine);
        partial[static_cast<std::size_t>(c)] = mine;
    }
    R total{};
    for (const R &p : partial)
        total.merge(p);
    return total;
}

// The first failure of a parallel loop, recorded per thread without a lock:
// each thread keeps its earliest record (by Record::before), and first()
// gives the earliest of all, the same whatever the thread count.
template <class Record>
class FirstFailure {
  public:
    FirstFailure() : slot_(static_cast<std::size_t>(max_threads())) {}
    void record(const Record &r) {
        Slot &s = slot_[static_cast<std::size_t>(thread_index())];
        if (!s.set || r.before(s.record)) s = Slot{true, r};
    }
    const Record *first() const {
        const Slot *best = nullptr;
        for (const Slot &s : slot_)
            if (s.set && (!best || s.record.before(best->record))) best = &s;
        return best ? &best->record : nullptr;
    }

  private:
    struct Slot {
        bool set = false;
        Record record{};
    };
    std::vector<Slot> slot_;
};

} // namespace talus::par
