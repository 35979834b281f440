#include "run_folder.hpp"

#include <talus/error.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/io/provenance.hpp>

#include <fmt/format.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <random>
#include <sys/file.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

namespace talus {

namespace fs = std::filesystem;

bool is_own_file(const fs::path &p) {
    const std::string name = p.filename().string();
    for (const char *f : {"diagnostics.csv", "probes.csv", "particles.pvd", "failed_call.yaml",
                          "final_particles.csv", "provenance.json", "stages.csv"})
        if (name == f) return true;
    if (name.rfind("particles_", 0) != 0 && name.rfind("failure_", 0) != 0) return false;
    std::error_code ec;
    return p.extension() == ".vtu" || p.extension() == ".pvtu" ||
           (p.extension().empty() && fs::is_directory(p, ec));
}

std::string new_run_id() {
    std::array<unsigned char, 16> b{};
    std::size_t got = 0;
    while (got < b.size()) {
        const ssize_t n = getrandom(b.data() + got, b.size() - got, 0);
        if (n > 0)
            got += static_cast<std::size_t>(n);
        else if (errno != EINTR)
            break;
    }
    if (got < b.size()) { // no getrandom: the name need only differ between runs
        std::random_device rd;
        for (unsigned char &c : b)
            c = static_cast<unsigned char>(rd());
    }
    std::string hex;
    for (unsigned char c : b)
        hex += fmt::format("{:02x}", c);
    return hex;
}

// ------------------------------------------------------ whose folder --

namespace {

std::string short_digest(const std::string &d) {
    return d.size() > 12 ? d.substr(0, 12) + "..." : d.empty() ? "none" : d;
}

// What a folder's provenance.json says of its run.
struct FolderRun {
    std::string run_id, created, scenario, scenario_sha256;
    std::vector<std::pair<std::string, std::string>> plugins; // material, plugin SHA-256
};

FolderRun read_folder_run(const fs::path &file) {
    // provenance.json is JSON, which the YAML reader reads.
    const yaml::Node root = yaml::load_file(file.string());
    FolderRun r;
    auto text = [](const yaml::Node &n) { return n.defined() ? n.as_string() : std::string(); };
    r.run_id = text(root.get("run_id"));
    r.created = text(root.get("created_utc"));
    r.scenario = text(root.get("input").get("file"));
    r.scenario_sha256 = text(root.get("input").get("sha256"));
    const yaml::Node ms = root.get("materials");
    for (std::size_t k = 0; ms.is_sequence() && k < ms.size(); ++k)
        r.plugins.emplace_back(text(ms.at(k).get("name")),
                               text(ms.at(k).get("library").get("sha256")));
    return r;
}

} // namespace

void refuse_foreign_folder(const fs::path &dir, const Checkpoint &c) {
    const fs::path prov = dir / "provenance.json";
    auto refuse = [&](const std::string &why) {
        throw Error(fmt::format("{}: not the folder of the checkpoint's run: {}\nthe run was not "
                                "continued and the folder is as it was; continue the run in its "
                                "own folder (--output-dir), the one its checkpoints/ folder is in",
                                dir.string(), why));
    };
    std::error_code ec;
    if (!fs::exists(prov, ec)) {
        for (const auto &e : fs::directory_iterator(dir, ec))
            if (is_own_file(e.path()))
                refuse(fmt::format("it holds a run's files ({}, ...) but no provenance.json "
                                   "that would say which run they are of",
                                   e.path().filename().string()));
        return; // an empty folder: the run's output continues there alone
    }
    FolderRun f;
    try {
        f = read_folder_run(prov);
    } catch (const Error &e) {
        refuse(fmt::format("its provenance.json cannot be read: {}", e.what()));
    }
    if (!f.run_id.empty() && !c.run_id.empty()) {
        if (f.run_id != c.run_id)
            refuse(fmt::format("it holds run {} (of {}, started {}); the checkpoint is of run "
                               "{} (of {})",
                               f.run_id, f.scenario, f.created, c.run_id, c.scenario_path));
        return; // the same run, whatever --force-restart changed since
    }
    // A folder or a checkpoint of a Talus that named no runs: the same
    // scenario and the same plugins, or another run.
    if (f.scenario_sha256 != c.scenario_sha256)
        refuse(fmt::format("it holds a run of {} (scenario SHA-256 {}); the checkpoint is of a "
                           "run of {} (SHA-256 {})",
                           f.scenario, short_digest(f.scenario_sha256), c.scenario_path,
                           short_digest(c.scenario_sha256)));
    for (const PluginIdentity &p : c.plugins) {
        std::string had;
        for (const auto &[material, sha] : f.plugins)
            if (material == p.material) had = sha;
        if (had != p.sha256)
            refuse(fmt::format("material '{}': its run's plugin had SHA-256 {}, the checkpoint's "
                               "{}",
                               p.material, short_digest(had), short_digest(p.sha256)));
    }
}

// ------------------------------------------------------ who writes now --

namespace {

// What the holder wrote into the lock file (it may not have yet).
std::string holder_of(int fd) {
    char buf[256] = {};
    const ssize_t n = pread(fd, buf, sizeof buf - 1, 0);
    std::string s = n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : std::string();
    while (!s.empty() && (s.back() == '\n' || s.back() == '\r'))
        s.pop_back();
    return s.empty() ? "a process that has not yet written its PID" : s;
}

} // namespace

FolderLock::FolderLock(const fs::path &dir, For purpose) : dir_(dir), file_(dir / kFileName) {
    std::error_code ec;
    if (purpose == For::new_run && !fs::exists(dir, ec)) {
        made_ = fs::create_directories(dir, ec);
        if (ec && !fs::is_directory(dir))
            throw Error(
                fmt::format("{}: cannot create the folder: {}", dir.string(), ec.message()));
    }
    // A holder that ends removes the file; a file opened just before that
    // is then no longer the one at the path, and is opened again.
    for (int attempt = 0;; ++attempt) {
        fd_ = ::open(file_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
        if (fd_ < 0)
            throw Error(fmt::format("{}: cannot open the folder's lock file: {}", file_.string(),
                                    std::strerror(errno)));
        int r;
        while ((r = flock(fd_, LOCK_EX | LOCK_NB)) != 0 && errno == EINTR) {
        }
        if (r != 0) {
            const int err = errno;
            const std::string holder = err == EWOULDBLOCK ? holder_of(fd_) : std::string();
            ::close(fd_);
            fd_ = -1;
            // A restart has no other folder to go to: its run's files are
            // in this one.
            if (err == EWOULDBLOCK)
                throw Error(fmt::format(
                    "{}: another run is writing into this folder: {}\n{}", dir.string(), holder,
                    purpose == For::new_run
                        ? "the run was not started; wait for that one to end, or choose "
                          "another --output-dir"
                        : "the run was not continued; a restart continues in its own run's "
                          "folder only: wait for the run writing there to end, or stop it"));
            // A file system without flock (Lustre mounted without it, NFS
            // without its lock daemon): the run goes on, unguarded, and
            // says so.
            if (err == ENOLCK || err == ENOSYS || err == EOPNOTSUPP) {
                warning_ = fmt::format("talus: warning: {}: the file system cannot lock files "
                                       "({}): a second run into this folder would not be "
                                       "refused; start one run per folder",
                                       dir.string(), std::strerror(err));
                ::unlink(file_.c_str());
                return;
            }
            throw Error(fmt::format("{}: cannot lock the folder's lock file ({}), so two runs "
                                    "into it could not be told apart",
                                    file_.string(), std::strerror(err)));
        }
        struct stat held {
        }, now{};
        if (fstat(fd_, &held) == 0 && ::stat(file_.c_str(), &now) == 0 &&
            held.st_dev == now.st_dev && held.st_ino == now.st_ino)
            break;
        ::close(fd_);
        fd_ = -1;
        if (attempt == 100)
            throw Error(fmt::format("{}: the lock file keeps being replaced", file_.string()));
    }
    char host[256] = {};
    gethostname(host, sizeof host - 1);
    const std::string me =
        fmt::format("talus, PID {} on {}, started {}\n", getpid(), host, utc_now());
    if (ftruncate(fd_, 0) != 0 ||
        pwrite(fd_, me.data(), me.size(), 0) != static_cast<ssize_t>(me.size())) {
        const int err = errno;
        ::close(fd_);
        fd_ = -1;
        throw Error(fmt::format("{}: cannot write the folder's lock file: {}", file_.string(),
                                std::strerror(err)));
    }
}

FolderLock::~FolderLock() {
    if (fd_ < 0) return;
    // Removed while still held, so that a run waiting for it finds the path
    // gone or new (the constructor's loop).
    ::unlink(file_.c_str());
    ::close(fd_);
    std::error_code ec;
    if (made_) fs::remove(dir_, ec); // only if the run left it empty
}

} // namespace talus
