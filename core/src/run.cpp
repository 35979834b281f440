#include <talus/run.hpp>

#include <talus/sdk/voigt.hpp>

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <ostream>
#include <sstream>

namespace talus {

namespace fs = std::filesystem;

fs::path default_output_dir(const std::string &scenario_file) {
    return fs::current_path() / fs::path(scenario_file).stem();
}

// -------------------------------------------------------------------- VTK --

namespace {

// One appended data array: its XML header and its bytes.
struct VtkArray {
    std::string name, type;
    int components = 1;
    std::vector<char> bytes;
    template <class T>
    void put(T v) {
        const char *p = reinterpret_cast<const char *>(&v);
        bytes.insert(bytes.end(), p, p + sizeof(T));
    }
};

} // namespace

void write_vtu(const fs::path &file, const Simulation &sim,
               const std::vector<std::string> &state_fields) {
    const Scenario &sc = sim.scenario();
    const int D = sc.dim;
    const std::size_t n = sim.particle_count();
    std::vector<VtkArray> point_data;
    // add() hands out references into point_data: no reallocation allowed.
    point_data.reserve(9 + state_fields.size());
    auto add = [&](const std::string &name, const std::string &type, int comps) -> VtkArray & {
        point_data.push_back(VtkArray{name, type, comps, {}});
        point_data.back().bytes.reserve(n * static_cast<std::size_t>(comps) * 8);
        return point_data.back();
    };
    VtkArray &id = add("id", "Int64", 1);
    VtkArray &grp = add("group", "Int32", 1);
    VtkArray &disp = add("displacement", "Float64", 3);
    VtkArray &vel = add("velocity", "Float64", 3);
    VtkArray &sig = add("stress", "Float64", 9);
    VtkArray &pp = add("p", "Float64", 1);
    VtkArray &qq = add("q", "Float64", 1);
    VtkArray &vol = add("volume", "Float64", 1);
    VtkArray &jj = add("J", "Float64", 1);
    // State variables by name across materials; a particle whose material
    // lacks one gets NaN (shown blank in ParaView).
    struct StateField {
        std::string name;
        std::uint32_t size = 1;
        std::size_t array = 0;
    };
    std::vector<StateField> sf;
    for (const std::string &name : state_fields) {
        std::uint32_t size = 0;
        for (const auto &m : sc.materials)
            for (const auto &v : m.spec.model->state())
                if (v.name == name) size = std::max(size, v.size);
        sf.push_back(StateField{name, size, point_data.size()});
        add(name, "Float64", static_cast<int>(size));
    }
    VtkArray points{"Points", "Float64", 3, {}};
    for (const ParticleSet &s : sim.sets()) {
        const Model &model = *sc.materials[s.material].spec.model;
        for (std::size_t p = 0; p < s.n; ++p) {
            id.put<std::int64_t>(s.id[p]);
            grp.put<std::int32_t>(s.group[p]);
            for (int d = 0; d < 3; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                const bool in = d < D;
                points.put<double>(in ? s.x[dd][p] : 0.0);
                disp.put<double>(in ? s.x[dd][p] - s.x0[dd][p] : 0.0);
                vel.put<double>(in ? s.v[dd][p] : 0.0);
            }
            const sdk::Vec6 v6 = Eigen::Map<const sdk::Vec6>(&s.stress[6 * p]);
            const sdk::Mat3 m = sdk::stress_to_matrix(v6);
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b)
                    sig.put<double>(m(a, b));
            pp.put<double>(sdk::mean_pressure(v6));
            qq.put<double>(sdk::von_mises(v6));
            vol.put<double>(s.J[p] * s.vol0[p]);
            jj.put<double>(s.J[p]);
            for (const StateField &f : sf) {
                const StateInfo *info = nullptr;
                for (const auto &v : model.state())
                    if (v.name == f.name) info = &v;
                for (std::uint32_t k = 0; k < f.size; ++k)
                    point_data[f.array].put<double>(
                        info && k < info->size ? s.state[s.state_size * p + info->offset + k]
                                               : std::numeric_limits<double>::quiet_NaN());
            }
        }
    }
    // One vertex cell per particle.
    VtkArray conn{"connectivity", "Int64", 1, {}}, offs{"offsets", "Int64", 1, {}},
        types{"types", "UInt8", 1, {}};
    for (std::size_t i = 0; i < n; ++i) {
        conn.put<std::int64_t>(static_cast<std::int64_t>(i));
        offs.put<std::int64_t>(static_cast<std::int64_t>(i + 1));
        types.put<std::uint8_t>(1); // VTK_VERTEX
    }

    std::ostringstream xml;
    std::uint64_t offset = 0;
    auto header = [&](const VtkArray &a, bool named) {
        xml << fmt::format(
            "        <DataArray type=\"{}\"{} NumberOfComponents=\"{}\" format=\"appended\" "
            "offset=\"{}\"/>\n",
            a.type, named ? fmt::format(" Name=\"{}\"", a.name) : std::string(), a.components,
            offset);
        offset += sizeof(std::uint64_t) + a.bytes.size();
    };
    xml << "<?xml version=\"1.0\"?>\n"
        << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
           "header_type=\"UInt64\">\n"
        << "  <UnstructuredGrid>\n"
        << fmt::format("    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", n, n)
        << "      <PointData>\n";
    for (const VtkArray &a : point_data)
        header(a, true);
    xml << "      </PointData>\n      <Points>\n";
    header(points, false);
    xml << "      </Points>\n      <Cells>\n";
    header(conn, true);
    header(offs, true);
    header(types, true);
    xml << "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n  <AppendedData "
           "encoding=\"raw\">\n   _";

    const fs::path tmp = file.string() + ".tmp";
    {
        std::ofstream out(tmp, std::ios::binary);
        if (!out) throw Error(fmt::format("{}: cannot write", file.string()));
        out << xml.str();
        auto blob = [&](const VtkArray &a) {
            const std::uint64_t len = a.bytes.size();
            out.write(reinterpret_cast<const char *>(&len), sizeof len);
            out.write(a.bytes.data(), static_cast<std::streamsize>(a.bytes.size()));
        };
        for (const VtkArray &a : point_data)
            blob(a);
        blob(points);
        blob(conn);
        blob(offs);
        blob(types);
        out << "\n  </AppendedData>\n</VTKFile>\n";
        if (!out) throw Error(fmt::format("{}: write failed", file.string()));
    }
    fs::rename(tmp, file);
}

// -------------------------------------------------------------- the run --

namespace {

const char *kOwnFiles[] = {"diagnostics.csv", "probes.csv", "particles.pvd"};

bool is_own_file(const fs::path &p) {
    const std::string name = p.filename().string();
    for (const char *f : kOwnFiles)
        if (name == f) return true;
    return name.rfind("particles_", 0) == 0 && p.extension() == ".vtu";
}

struct ProbeTarget {
    const Probe *probe;
    std::int64_t particle = -1; // for particle probes
};

std::string fmt_time(double s) {
    if (!std::isfinite(s)) return "?";
    const long t = static_cast<long>(s + 0.5);
    return fmt::format("{}:{:02d}:{:02d}", t / 3600, (t / 60) % 60, t % 60);
}

} // namespace

RunSummary run_scenario(Scenario &sc, const RunOptions &opt, std::ostream &log) {
    const fs::path dir = opt.output_dir.empty() ? default_output_dir(sc.file) : opt.output_dir;
    // Refuse before any work: a previous run's files are never overwritten
    // silently.
    std::error_code ec;
    if (fs::exists(dir, ec)) {
        if (!fs::is_directory(dir, ec))
            throw Error(fmt::format("{}: exists and is not a directory", dir.string()));
        std::vector<fs::path> previous;
        for (const auto &e : fs::directory_iterator(dir))
            if (is_own_file(e.path())) previous.push_back(e.path());
        if (!previous.empty()) {
            if (!opt.force)
                throw Error(fmt::format(
                    "{}: holds the output of a previous run ({} and {} more file(s)); "
                    "pass --force to overwrite it, or choose another --output-dir",
                    dir.string(), previous.front().filename().string(), previous.size() - 1));
            for (const auto &p : previous)
                fs::remove(p);
        }
    }
    Simulation sim(sc, opt.solver);
    fs::create_directories(dir);

    // State variables to write: those named in output.state, else every one
    // its plugin flags for output.
    std::vector<std::string> state_fields = sc.output.state_fields;
    if (sc.output.all_flagged_state)
        for (const auto &m : sc.materials)
            for (const auto &v : m.spec.model->state())
                if (v.output() && std::find(state_fields.begin(), state_fields.end(), v.name) ==
                                      state_fields.end())
                    state_fields.push_back(v.name);

    // Probes: the particle nearest each point at t = 0.
    std::vector<ProbeTarget> probes;
    for (const Probe &p : sc.output.probes) {
        ProbeTarget t{&p, -1};
        if (p.kind == Probe::Kind::particle) {
            double best = std::numeric_limits<double>::infinity();
            for (const auto &s : sim.sets())
                for (std::size_t k = 0; k < s.n; ++k) {
                    double d2 = 0.0;
                    for (int d = 0; d < sc.dim; ++d)
                        d2 += std::pow(s.x[static_cast<std::size_t>(d)][k] -
                                           p.point[static_cast<std::size_t>(d)],
                                       2);
                    if (d2 < best) {
                        best = d2;
                        t.particle = s.id[k];
                    }
                }
        }
        probes.push_back(t);
    }
    const char *axes = "xyz";
    std::ofstream diag(dir / "diagnostics.csv"), prob;
    diag << "step,time,dt,mass,momentum_x,momentum_y,momentum_z,kinetic_energy,stress_work,"
            "angular_momentum_x,angular_momentum_y,angular_momentum_z,particles,removed,cut_steps,"
            "held_at_faces\n";
    if (!probes.empty()) {
        prob.open(dir / "probes.csv");
        prob << "time";
        for (const auto &t : probes) {
            const std::string &nm = t.probe->name;
            for (int d = 0; d < sc.dim; ++d)
                prob << ',' << nm << '.' << axes[d];
            if (t.probe->kind == Probe::Kind::particle)
                for (int d = 0; d < sc.dim; ++d)
                    prob << ',' << nm << ".u" << axes[d];
            for (int d = 0; d < sc.dim; ++d)
                prob << ',' << nm << ".v" << axes[d];
            if (t.probe->kind == Probe::Kind::particle)
                for (const char *c : {"xx", "yy", "zz", "xy", "yz", "xz"})
                    prob << ',' << nm << ".sig_" << c;
        }
        prob << '\n';
    }

    std::vector<std::pair<double, std::string>> pvd;
    int outputs = 0;
    auto write_outputs = [&]() {
        const Diagnostics dg = sim.diagnostics();
        diag << fmt::format("{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:."
                            "17g},{:.17g},{:.17g},"
                            "{},{},{},{}\n",
                            dg.step, dg.time, dg.dt, dg.mass, dg.momentum[0], dg.momentum[1],
                            dg.momentum[2], dg.kinetic_energy, dg.stress_work,
                            dg.angular_momentum[0], dg.angular_momentum[1], dg.angular_momentum[2],
                            dg.particles, dg.removed, dg.cut_steps, dg.held_at_faces);
        diag.flush();
        if (!probes.empty()) {
            prob << fmt::format("{:.17g}", sim.time());
            for (const auto &t : probes) {
                if (t.probe->kind == Probe::Kind::particle) {
                    bool found = false;
                    for (const auto &s : sim.sets())
                        for (std::size_t k = 0; k < s.n && !found; ++k)
                            if (s.id[k] == t.particle) {
                                found = true;
                                for (int d = 0; d < sc.dim; ++d)
                                    prob << fmt::format(",{:.17g}",
                                                        s.x[static_cast<std::size_t>(d)][k]);
                                for (int d = 0; d < sc.dim; ++d)
                                    prob << fmt::format(",{:.17g}",
                                                        s.x[static_cast<std::size_t>(d)][k] -
                                                            s.x0[static_cast<std::size_t>(d)][k]);
                                for (int d = 0; d < sc.dim; ++d)
                                    prob << fmt::format(",{:.17g}",
                                                        s.v[static_cast<std::size_t>(d)][k]);
                                for (int c = 0; c < 6; ++c)
                                    prob << fmt::format(
                                        ",{:.17g}", s.stress[6 * k + static_cast<std::size_t>(c)]);
                            }
                    if (!found) // removed after leaving the grid
                        for (int c = 0; c < 3 * sc.dim + 6; ++c)
                            prob << ",nan";
                } else {
                    double m = 0.0, x[3] = {0, 0, 0}, v[3] = {0, 0, 0};
                    for (const auto &s : sim.sets())
                        for (std::size_t k = 0; k < s.n; ++k)
                            if (static_cast<std::size_t>(s.group[k]) == t.probe->group) {
                                m += s.mass[k];
                                for (int d = 0; d < sc.dim; ++d) {
                                    x[d] += s.mass[k] * s.x[static_cast<std::size_t>(d)][k];
                                    v[d] += s.mass[k] * s.v[static_cast<std::size_t>(d)][k];
                                }
                            }
                    for (int d = 0; d < sc.dim; ++d)
                        prob << fmt::format(",{:.17g}", m > 0 ? x[d] / m : NAN);
                    for (int d = 0; d < sc.dim; ++d)
                        prob << fmt::format(",{:.17g}", m > 0 ? v[d] / m : NAN);
                }
            }
            prob << '\n';
            prob.flush();
        }
        if (sc.output.vtk) {
            const std::string name = fmt::format("particles_{:05d}.vtu", outputs);
            write_vtu(dir / name, sim, state_fields);
            pvd.emplace_back(sim.time(), name);
            // Rewritten after every frame so that a run stopped early still
            // leaves a valid collection.
            std::ofstream c(dir / "particles.pvd.tmp");
            c << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\" "
                 "byte_order=\"LittleEndian\">\n  <Collection>\n";
            for (const auto &[t, f] : pvd)
                c << fmt::format("    <DataSet timestep=\"{:.17g}\" part=\"0\" file=\"{}\"/>\n", t,
                                 f);
            c << "  </Collection>\n</VTKFile>\n";
            c.close();
            fs::rename(dir / "particles.pvd.tmp", dir / "particles.pvd");
        }
        ++outputs;
    };

    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    double last_progress = -1.0;
    long particle_steps = 0;
    std::size_t warnings_shown = 0;
    write_outputs();
    const double end = sc.end_time;
    if (opt.progress) {
        // From the initial state's stable step (or the fixed one): a lower
        // bound when the material speeds up, said as an estimate.
        const double dt0 = sc.solver.dt ? *sc.solver.dt : sim.critical_dt();
        log << fmt::format("talus: {} particles; about {:.3g} steps of {:.3g} s to t = {:g} s "
                           "(estimated from the initial state)\n",
                           sim.particle_count(), std::ceil(end / dt0), dt0, end);
    }
    const double every = sc.output.every > 0.0 ? sc.output.every : end;
    // Output k is due at k * every; it is written after the first step that
    // reaches that time (the file and the CSV rows carry the actual time).
    // Steps are never shortened for an output, so the trajectory does not
    // depend on the cadence; only the last step is cut to end on `end`.
    long next_k = 1;
    auto due = [&] { return std::min(static_cast<double>(next_k) * every, end); };
    // Times within a millionth of a step of a target count as reaching it.
    while (sim.time() < end * (1.0 - 1e-12)) {
        sim.step(end - sim.time());
        particle_steps += static_cast<long>(sim.particle_count());
        for (; warnings_shown < sim.warnings().size(); ++warnings_shown)
            log << "talus: warning: " << sim.warnings()[warnings_shown] << '\n';
        if (sim.time() >= due() - 1e-9 * sim.last_dt()) {
            write_outputs();
            // One file per output time reached, even if a long step passed
            // several of them.
            while (due() <= sim.time() + 1e-9 * sim.last_dt() && due() < end)
                ++next_k;
        }
        const double interval = opt.progress_tty ? 0.5 : opt.progress_interval;
        if (opt.progress && elapsed() - last_progress > interval) {
            last_progress = elapsed();
            const double rate = static_cast<double>(particle_steps) / std::max(last_progress, 1e-9);
            const double eta = last_progress * (end - sim.time()) / std::max(sim.time(), 1e-300);
            std::fprintf(stderr,
                         "%sstep %ld  t = %.4g / %.4g s  dt = %.3g s  elapsed %s  ETA %s  %.3g "
                         "particle-steps/s%s",
                         opt.progress_tty ? "\r" : "talus: progress: ", sim.steps(), sim.time(),
                         end, sim.last_dt(), fmt_time(last_progress).c_str(), fmt_time(eta).c_str(),
                         rate, opt.progress_tty ? "   " : "\n");
            std::fflush(stderr);
        }
    }
    if (opt.progress && opt.progress_tty) std::fprintf(stderr, "\n");
    RunSummary rs;
    rs.steps = sim.steps();
    rs.time = sim.time();
    rs.seconds = elapsed();
    rs.particles = sim.particle_count();
    rs.particle_steps_per_second = static_cast<double>(particle_steps) / std::max(rs.seconds, 1e-9);
    rs.outputs = outputs;
    rs.output_dir = dir;
    return rs;
}

} // namespace talus
