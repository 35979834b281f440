// talus_bench: particle-steps per second of the explicit MPM cycle, one JSON
// line per case. Measures; asserts nothing (see bench/README.md).
//
//   talus_bench [--steps N] [--repeat R] [--case NAME] [--threads T[,T...]] [--busy N]
//               [--profile] [--all-nodes] [--material-path plugin|inline_hooke]
//   talus_bench --scenario NAME   (prints the case's scenario, for `talus run`)
//   mpirun -np N talus_bench ...   (the cases spread over N ranks; rank 0 prints)
#include <talus/input/scenario_yaml.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/mpm/simulation.hpp>

#include "inline_hooke.hpp"

#include <fmt/format.h>

#include <omp.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace {

// CPU-bound processes that run beside the cases (--busy N): what a 2-thread
// run does when another program takes a core. Each child spins until the
// benchmark ends (killed then, or with it if the benchmark dies).
class BusyProcesses {
  public:
    explicit BusyProcesses(int n) {
        for (int k = 0; k < n; ++k) {
            const pid_t pid = fork();
            if (pid < 0) {
                std::perror("talus_bench: fork");
                std::exit(1);
            }
            if (pid == 0) {
                prctl(PR_SET_PDEATHSIG, SIGKILL);
                volatile unsigned long spin = 0;
                for (;;)
                    spin = spin + 1;
            }
            children_.push_back(pid);
        }
    }
    ~BusyProcesses() {
        for (const pid_t pid : children_) {
            kill(pid, SIGKILL);
            waitpid(pid, nullptr, 0);
        }
    }
    BusyProcesses(const BusyProcesses &) = delete;
    BusyProcesses &operator=(const BusyProcesses &) = delete;

  private:
    std::vector<pid_t> children_;
};

struct Case {
    std::string name;
    int dim;
    std::string yaml;
};

// A block of linear_elastic particles settling on a slip floor under gravity:
// every phase of the cycle does real work (stress, gravity, a boundary).
// `solver` is the solver mapping's body; the default is the common USL/FLIP
// set-up, the others exercise each scheme, transfer and kernel.
constexpr const char *kUslFlip =
    "scheme: usl, transfer: {type: flip, alpha: 0.99}, shape: bspline2, cfl: 0.3";
constexpr const char *kElastic =
    "{model: linear_elastic, density: 2000, youngs_modulus: 1.0e7, poisson_ratio: 0.3}";
// Cohesive-frictional soil in its geostatic state (K0 = 0.5) with free
// sides: within the timed steps the sides and the layer on the floor yield
// (12 % of the points of a 64k block after 28 steps), the core stays
// elastic, so batches mix elastic and plastic points.
constexpr const char *kMohrCoulomb =
    "{model: mohr_coulomb, density: 2000, youngs_modulus: 1.0e7, poisson_ratio: 0.3, "
    "friction_angle: 30, dilation_angle: 0, cohesion: 2000}";
std::string block_yaml(int dim, int nx, int ny, int nz, int ppc, double h,
                       const std::string &solver = kUslFlip,
                       const std::string &material = kElastic) {
    const double lx = nx * h, ly = ny * h, lz = nz * h;
    const std::string origin = dim == 2 ? "[0, 0]" : "[0, 0, 0]";
    const std::string size = dim == 2
                                 ? fmt::format("[{}, {}]", lx + 2 * h, ly + 2 * h)
                                 : fmt::format("[{}, {}, {}]", lx + 2 * h, ly + 2 * h, lz + 2 * h);
    const std::string bmin =
        dim == 2 ? fmt::format("[{}, {}]", h, h) : fmt::format("[{}, {}, {}]", h, h, h);
    const std::string bmax = dim == 2 ? fmt::format("[{}, {}]", h + lx, h + ly)
                                      : fmt::format("[{}, {}, {}]", h + lx, h + ly, h + lz);
    const std::string g = dim == 2 ? "[0, -9.81]" : "[0, 0, -9.81]";
    const std::string floor = dim == 2 ? "y-" : "z-";
    return fmt::format(
        "talus: 1\ndimension: {}\n"
        "grid: {{origin: {}, size: {}, cell: {}}}\n"
        "materials:\n  soil: {}\n"
        "groups:\n  block: {{material: soil, particles_per_cell: {}, shape: {{box: {{min: {}, max: "
        "{}}}}}{}}}\n"
        "boundaries: {{{}: slip}}\n"
        "gravity: {}\n"
        "solver: {{{}}}\n"
        "time: {{end: 1.0}}\n",
        dim, origin, size, h, material, ppc, bmin, bmax,
        material == kElastic ? "" : ", initial_stress: {geostatic: {k0: 0.5}}", floor, g, solver);
}

// A linear_elastic disk spinning at 20 rad/s about its centre, no gravity,
// no boundary: at its rim particles cross a cell every 30 steps or so, so
// particles change cell and slab at every step, and the order in memory
// decays as in a flowing body (the re-sort's rule and the slab binning at
// work: docs/performance.md, "When to re-sort"). 2D: 1M particles.
std::string spinning_disk_yaml() {
    return fmt::format("talus: 1\ndimension: 2\n"
                       "grid: {{origin: [0, 0], size: [2, 2], cell: 0.002}}\n"
                       "materials:\n  solid: {}\n"
                       "groups:\n  disk: {{material: solid, particles_per_cell: 2, shape: "
                       "{{sphere: {{center: [1, 1], radius: 0.56}}}}, angular_velocity: 20.0}}\n"
                       "solver: {{{}}}\n"
                       "time: {{end: 1.0}}\n",
                       kElastic, kUslFlip);
}

// The machine's memory bandwidth, the roof of docs/performance.md: a
// read-only sum and the STREAM triad a = b + s c over arrays far larger
// than the caches, with the same threads as the cases (static shares, each
// thread first touching its own part). Bytes as STREAM counts them: 8 per
// value read or written (the write's read for ownership not counted).
void memory_bandwidth(int threads, int repeat) {
    const std::size_t n = std::size_t{1} << 25; // 32 Mi doubles: 256 MiB per array
    std::unique_ptr<double[]> a(new double[n]), b(new double[n]), c(new double[n]);
    const int used = threads > 0 ? threads : omp_get_max_threads();
    const auto len = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static) num_threads(used)
    for (std::ptrdiff_t i = 0; i < len; ++i) {
        a[static_cast<std::size_t>(i)] = 1.0;
        b[static_cast<std::size_t>(i)] = 2.0;
        c[static_cast<std::size_t>(i)] = 0.5;
    }
    auto best_of = [&](auto &&kernel) {
        double best = 1e300;
        for (int r = 0; r < std::max(repeat, 3); ++r) {
            const auto t0 = std::chrono::steady_clock::now();
            kernel();
            best = std::min(
                best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        }
        return best;
    };
    // The read: eight running sums per thread, so that the adds' latency
    // (a single sum is one dependent chain) does not bound it.
    double sum = 0.0;
    const double read = best_of([&] {
        double s = 0.0;
#pragma omp parallel for schedule(static) num_threads(used) reduction(+ : s)
        for (std::ptrdiff_t i = 0; i < len / 8; ++i) {
            const double *p = &a[8 * static_cast<std::size_t>(i)];
            double part[8];
            for (int k = 0; k < 8; ++k)
                part[k] = p[k];
            s += ((part[0] + part[1]) + (part[2] + part[3])) +
                 ((part[4] + part[5]) + (part[6] + part[7]));
        }
        sum = s;
    });
    const double triad = best_of([&] {
#pragma omp parallel for schedule(static) num_threads(used)
        for (std::ptrdiff_t i = 0; i < len; ++i) {
            const auto k = static_cast<std::size_t>(i);
            a[k] = b[k] + 0.5 * c[k];
        }
    });
    const double bytes = 8.0 * static_cast<double>(n);
    // `check` keeps the sums alive (and shows the arrays held what was written).
    std::printf("{\"case\": \"memory_bandwidth\", \"threads\": %d, \"read_gb_per_s\": %.1f, "
                "\"triad_gb_per_s\": %.1f, \"check\": %.0f}\n",
                used, bytes / read / 1e9, 3.0 * bytes / triad / 1e9, sum / static_cast<double>(n));
    std::fflush(stdout);
}

// How far apart two of the case's threads run: the one-way time for a
// store by one thread to reach another, from a counter that threads 0 and
// 1 hand back and forth (each waits for its turn, then passes it on; best
// of the repeats). Cores that share a last-level cache hand a line over in
// tens of nanoseconds; cores on different dies (chiplets, sockets) take
// hundreds, and then data one thread wrote in a step and another reads in
// the next crosses between caches (docs/performance.md, "The two cores
// share no cache"). In seconds, best of the repeats; nothing where fewer
// than two threads run (the JSON line then says null).
std::optional<double> one_way_seconds(int threads, int repeat) {
    const int used = threads > 0 ? threads : omp_get_max_threads();
    if (used < 2) return std::nullopt;
    constexpr long kHandovers = 1'000'000;
    alignas(64) std::atomic<long> turn{0};
    double best = 1e300;
    for (int r = 0; r < std::max(repeat, 3); ++r) {
        turn.store(0);
        double seconds = 0.0;
        bool alone = false;
#pragma omp parallel num_threads(2)
        {
            const long me = omp_get_thread_num();
            // A runtime that grants one thread (OMP_THREAD_LIMIT=1) would
            // leave it waiting for a turn nobody passes.
            if (omp_get_num_threads() < 2) {
                alone = true;
            } else {
                const auto t0 = std::chrono::steady_clock::now();
                for (long i = me; i < 2 * kHandovers; i += 2) {
                    while (turn.load(std::memory_order_acquire) != i) {
#if defined(__x86_64__) || defined(__i386__)
                        __builtin_ia32_pause();
#endif
                    }
                    turn.store(i + 1, std::memory_order_release);
                }
                if (me == 0) {
                    while (turn.load(std::memory_order_acquire) != 2 * kHandovers) {
                    }
                    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
                                  .count();
                }
            }
        }
        if (alone) return std::nullopt;
        best = std::min(best, seconds / static_cast<double>(2 * kHandovers));
    }
    return best;
}

void core_to_core(int threads, int repeat) {
    if (const std::optional<double> t = one_way_seconds(threads, repeat))
        std::printf("{\"case\": \"core_to_core\", \"threads\": 2, \"one_way_ns\": %.1f}\n",
                    *t * 1e9);
    else
        std::printf("{\"case\": \"core_to_core\", \"threads\": 1, \"one_way_ns\": null}\n");
    std::fflush(stdout);
}

} // namespace

int main(int argc, char **argv) {
    // MPI only under a launcher: a plain run's memory is the solver's.
    std::optional<talus::MpiSession> mpi;
    if (talus::MpiSession::launched_ranks() > 1) mpi.emplace(&argc, &argv);
    const talus::Comm comm = talus::Comm::world();
    const bool rank0 = comm.rank() == 0;
    // 25 steps: the block hardly moves in them, so no re-sort falls in the
    // window (docs/performance.md, "When to re-sort", gives its cost).
    int steps = 25, repeat = 3;
    std::vector<int> thread_counts{0}; // 0: OpenMP's default
    bool profile = false, all_nodes = false;
    // Which material update is measured: the plugins through the C ABI, or
    // linear_elastic's done by the host (inline_hooke.hpp).
    std::string material_path = "plugin";
    int busy = 0;
    std::string only;
    bool print_scenario = false;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) {
                std::fprintf(stderr, "talus_bench: %s needs a value\n", a.c_str());
                std::exit(2);
            }
            return argv[++i];
        };
        if (a == "--steps")
            steps = std::atoi(next().c_str());
        else if (a == "--repeat")
            repeat = std::atoi(next().c_str());
        else if (a == "--threads") {
            // One count or a list ("1,2"): every case runs with each.
            thread_counts.clear();
            const std::string list = next();
            for (std::size_t b = 0; b <= list.size();) {
                const std::size_t e = std::min(list.find(',', b), list.size());
                const int n = std::atoi(list.substr(b, e - b).c_str());
                if (n < 1) {
                    std::fprintf(stderr, "talus_bench: --threads expects counts >= 1, got '%s'\n",
                                 list.c_str());
                    return 2;
                }
                thread_counts.push_back(n);
                b = e + 1;
            }
        } else if (a == "--case")
            only = next();
        else if (a == "--scenario") {
            only = next();
            print_scenario = true;
        } else if (a == "--profile")
            profile = true;
        else if (a == "--all-nodes")
            all_nodes = true;
        else if (a == "--material-path") {
            material_path = next();
            if (material_path != "plugin" && material_path != "inline_hooke") {
                std::fprintf(
                    stderr,
                    "talus_bench: --material-path expects plugin or inline_hooke, got '%s'\n",
                    material_path.c_str());
                return 2;
            }
        } else if (a == "--busy") {
            busy = std::atoi(next().c_str());
            if (busy < 0) {
                std::fprintf(stderr, "talus_bench: --busy expects a count >= 0\n");
                return 2;
            }
        } else {
            std::fprintf(stderr, "usage: talus_bench [--steps N] [--repeat R] [--case NAME] "
                                 "[--threads T[,T...]] [--busy N] [--profile] [--all-nodes] "
                                 "[--material-path plugin|inline_hooke] | --scenario NAME\n");
            return 2;
        }
    }
    if (steps < 1 || repeat < 1) {
        std::fprintf(stderr, "talus_bench: --steps and --repeat expect counts >= 1\n");
        return 2;
    }
    // About 1M particles each: 3D 100^3 (2x2x2 per cell), 2D 1000^2 (2x2).
    // The odd case has a particle count with no power-of-two factors, so
    // that array sizes cannot alias in cache (DESIGN section 10).
    const std::vector<Case> cases = {
        {"3d_block_bspline2_linear_elastic", 3, block_yaml(3, 50, 50, 50, 2, 0.02)},
        {"3d_block_odd_bspline2_linear_elastic", 3, block_yaml(3, 49, 51, 53, 2, 0.02)},
        {"2d_block_bspline2_linear_elastic", 2, block_yaml(2, 500, 500, 0, 2, 0.002)},
        {"2d_disk_spinning_linear_elastic", 2, spinning_disk_yaml()},
        // The other schemes, transfers and kernels, 2D at a quarter of the
        // size and one 3D: each takes its own path through the cycle.
        {"2d_block_musl_apic_bspline2", 2,
         block_yaml(2, 250, 250, 0, 2, 0.004,
                    "scheme: musl, transfer: apic, shape: bspline2, cfl: 0.3")},
        {"2d_block_usf_flip_gimp", 2,
         block_yaml(2, 250, 250, 0, 2, 0.004,
                    "scheme: usf, transfer: {type: flip, alpha: 0.99}, shape: gimp, cfl: 0.3")},
        {"2d_block_usavg_tpic_bspline3", 2,
         block_yaml(2, 250, 250, 0, 2, 0.004,
                    "scheme: usavg, transfer: tpic, shape: bspline3, cfl: 0.3")},
        {"3d_block_usl_apic_dilation_bspline2", 3,
         block_yaml(3, 32, 32, 32, 2, 0.02,
                    "scheme: usl, transfer: apic, shape: bspline2, cfl: 0.3, "
                    "cell_averaged_dilation: true")},
        // Mohr-Coulomb with its state variables, elastic core and failing
        // sides: the plugin's cost beside linear_elastic's.
        {"3d_block_bspline2_mohr_coulomb", 3,
         block_yaml(3, 50, 50, 50, 2, 0.02, kUslFlip, kMohrCoulomb)},
        {"2d_block_bspline2_mohr_coulomb", 2,
         block_yaml(2, 500, 500, 0, 2, 0.002, kUslFlip, kMohrCoulomb)},
        // How the cost grows with size: 64k (the grid in cache) to 4M.
        {"3d_block_64k", 3, block_yaml(3, 20, 20, 20, 2, 0.02)},
        {"3d_block_4m", 3, block_yaml(3, 80, 80, 80, 2, 0.02)},
        {"2d_block_64k", 2, block_yaml(2, 128, 128, 0, 2, 0.002)},
        {"2d_block_4m", 2, block_yaml(2, 1000, 1000, 0, 2, 0.002)},
        // A domain four times (2D) or twice to four times (3D) as long as
        // it is high, as a slope's: 1M particles, the block's set-up.
        {"2d_wide_bspline2_linear_elastic", 2, block_yaml(2, 1000, 250, 0, 2, 0.002)},
        {"3d_wide_bspline2_linear_elastic", 3, block_yaml(3, 100, 50, 25, 2, 0.02)},
    };
    // A misspelt --case would otherwise measure nothing and exit 0.
    if (!only.empty() && only != "memory_bandwidth" && only != "core_to_core" &&
        std::none_of(cases.begin(), cases.end(), [&](const Case &c) { return c.name == only; })) {
        std::fprintf(stderr,
                     "talus_bench: no case '%s'; the cases are: memory_bandwidth, core_to_core",
                     only.c_str());
        for (const Case &c : cases)
            std::fprintf(stderr, ", %s", c.name.c_str());
        std::fprintf(stderr, "\n");
        return 2;
    }
    if (print_scenario) {
        for (const Case &c : cases)
            if (c.name == only) {
                std::fputs(c.yaml.c_str(), stdout);
                return 0;
            }
        std::fprintf(stderr, "talus_bench: --scenario takes a case of a scenario, not '%s'\n",
                     only.c_str());
        return 2;
    }
    const BusyProcesses beside(busy);
    try {
        if ((only.empty() || only == "memory_bandwidth") && !comm.distributed())
            for (const int threads : thread_counts)
                memory_bandwidth(threads, repeat);
        if ((only.empty() || only == "core_to_core") && !comm.distributed())
            for (const int threads : thread_counts)
                core_to_core(threads, repeat);
        for (const Case &c : cases)
            for (const int threads : thread_counts) {
                if (!only.empty() && c.name != only) continue;
                talus::PluginRegistry registry;
                const talus::yaml::Node root = talus::yaml::load_string(c.yaml, c.name + ".yaml");
                talus::Scenario sc = talus::read_scenario(root, registry);
                talus::SolverOptions so;
                so.threads = threads;
                so.comm = comm;
                so.active_nodes_only = !all_nodes;
                if (material_path == "inline_hooke") so.material_hook = talus::bench::inline_hooke;
                // Every run starts from the scenario's initial state: a
                // continued run would time a different state each time (a
                // Mohr-Coulomb block goes from 0.3 % to 97 % plastic points
                // over three runs), and best and median would then compare
                // different work. Only the timed steps count in the phase
                // shares, traffic and barriers.
                std::vector<double> times;
                long regions = 0;
                std::size_t halo_bytes = 0, migration_bytes = 0;
                std::array<double, talus::Simulation::kPhases> phases{};
                double n = 0.0, particle_bytes = 0.0, rss = 0.0;
                // The grid's nodes each timed step reset and updated, as a
                // share of all (rank 0's).
                double active_share = 0.0;
                std::string isa;
                for (int r = 0; r < repeat; ++r) {
                    talus::Simulation sim(sc, so);
                    for (int w = 0; w < 2; ++w)
                        sim.step(1.0); // warm caches and the allocator
                    const long regions0 = talus::Simulation::parallel_regions();
                    const talus::RankTraffic traffic0 = sim.traffic();
                    const auto phases0 = sim.phase_seconds();
                    // On several ranks: from a common start to the last
                    // rank's end.
                    comm.barrier();
                    const auto t0 = std::chrono::steady_clock::now();
                    for (int s = 0; s < steps; ++s) {
                        sim.step(1.0);
                        active_share += static_cast<double>(sim.active_nodes()) /
                                        static_cast<double>(sim.grid_nodes());
                    }
                    const double sec =
                        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
                            .count();
                    times.push_back(comm.max(sec));
                    regions += talus::Simulation::parallel_regions() - regions0;
                    const talus::RankTraffic traffic1 = sim.traffic();
                    halo_bytes += traffic1.halo_bytes - traffic0.halo_bytes;
                    migration_bytes += traffic1.migration_bytes - traffic0.migration_bytes;
                    const auto phases1 = sim.phase_seconds();
                    for (std::size_t k = 0; k < phases.size(); ++k)
                        phases[k] += phases1[k] - phases0[k];
                    n = static_cast<double>(sim.particle_count());
                    // Bytes of the particle arrays per particle.
                    particle_bytes = 0.0;
                    for (talus::ParticleSet &set : sim.sets())
                        particle_bytes += static_cast<double>(set.bytes_per_particle()) *
                                          static_cast<double>(set.n);
                    isa = sim.kernel_isa();
                    // The peak resident memory with the first simulation
                    // alive (all ranks' peaks): the later ones reuse freed
                    // memory that the allocator then keeps differently
                    // (glibc raises its mmap threshold after a large free),
                    // which a run of `talus` never sees.
                    if (r == 0) {
                        rusage usage{};
                        getrusage(RUSAGE_SELF, &usage);
                        rss = comm.sum(1024.0 * static_cast<double>(usage.ru_maxrss));
                    }
                }
                // Per rank and step in the timed steps: the seconds in the
                // halo sums and the migration, and the bytes sent (the
                // most of any rank).
                const double timed = static_cast<double>(repeat) * steps;
                auto per_step = [&](double v) { return comm.max(v) / timed; };
                const int halo_k = talus::Simulation::kPhases - 2, mig_k = halo_k + 1;
                const double halo_s = per_step(phases[halo_k]);
                const double mig_s = per_step(phases[mig_k]);
                const double halo_b = per_step(static_cast<double>(halo_bytes));
                const double mig_b = per_step(static_cast<double>(migration_bytes));
                std::sort(times.begin(), times.end());
                const double best = times.front();
                const std::size_t mid = times.size() / 2;
                const double median =
                    times.size() % 2 ? times[mid] : 0.5 * (times[mid - 1] + times[mid]);
                const double barriers = static_cast<double>(regions) / timed;
                // The particle arrays' bytes per particle, and the process's
                // peak resident memory (grid, ordering and everything else
                // included) per particle: the case's own peak when it runs
                // alone (--case), else the largest so far.
                particle_bytes = comm.sum(particle_bytes);
                const int used = talus::Simulation::max_threads();
                // Each phase's share of the time in the step's phases over
                // the timed steps, in the JSON line and with --profile on
                // stderr as a table.
                double total = 0.0;
                for (double v : phases)
                    total += v;
                std::string shares;
                for (int k = 0; k < talus::Simulation::kPhases; ++k) {
                    const double share = phases[static_cast<std::size_t>(k)] / total;
                    shares += fmt::format("{}\"{}\": {:.3f}", k ? ", " : "",
                                          talus::Simulation::phase_name(k), share);
                    if (profile && rank0)
                        std::fprintf(stderr, "  %-28s %6.1f %%\n", talus::Simulation::phase_name(k),
                                     100.0 * share);
                }
                if (!rank0) continue;
                std::printf("{\"case\": \"%s\", \"dim\": %d, \"particles\": %.0f, \"steps\": %d, "
                            "\"ranks\": %d, \"threads\": %d, \"kernels\": \"%s\", "
                            "\"material_path\": \"%s\", "
                            "\"busy_processes\": %d, \"seconds\": %.4f, "
                            "\"particle_steps_per_second\": %.4g, "
                            "\"median_particle_steps_per_second\": %.4g, "
                            "\"particle_bytes\": %.0f, \"max_rss_bytes_per_particle\": %.0f, "
                            "\"barriers_per_step\": %.1f, \"active_node_share\": %.3f, "
                            "\"halo_seconds_per_step\": %.3g, "
                            "\"migration_seconds_per_step\": %.3g, "
                            "\"halo_bytes_per_rank_step\": %.0f, "
                            "\"migration_bytes_per_rank_step\": %.0f, \"phase_shares\": {%s}}\n",
                            c.name.c_str(), c.dim, n, steps, comm.size(), used, isa.c_str(),
                            material_path.c_str(), busy, best, n * steps / best, n * steps / median,
                            particle_bytes / n, rss / n, barriers,
                            active_share / (static_cast<double>(repeat) * steps), halo_s, mig_s,
                            halo_b, mig_b, shares.c_str());
                std::fflush(stdout);
            }
    } catch (const std::exception &e) {
        std::fprintf(stderr, "talus_bench: %s\n", e.what());
        talus::MpiSession::abort(1);
    }
    return 0;
}
