// Checkpoints in HDF5 (talus/io/checkpoint.hpp). Layout (h5dump -H shows
// it): root attributes for the format, versions and every scalar of the
// state; /scenario (the text as read); /plugins/<k> (one group per
// material, attributes only); /sets/<k>/<column> (n x stride arrays of the
// particle columns, named as ParticleSet names them) and /sets/<k>/slab_of;
// /output (frame times, probe particles). Every HDF5 call is checked, and
// the file's bytes carry digests in its user block (checkpoint_digests.hpp).
#include <talus/io/checkpoint.hpp>

#include "checkpoint_digests.hpp"

#include <talus/error.hpp>
#include <talus/material/plugin_loader.hpp>
#include <talus/material_abi.h>
#include <talus/regular_file.hpp>

#include <fmt/format.h>
#include <hdf5.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>

#ifndef TALUS_VERSION_STRING
#define TALUS_VERSION_STRING "0.0.0"
#endif

namespace talus {

namespace fs = std::filesystem;

namespace {

constexpr const char *kFormat = "talus checkpoint";
// 2: a run on several ranks writes one file per rank (the rank and every
// rank's cell box in each). A format-1 file is one rank's and reads as one.
// 3: in plane strain a particle's F is its in-plane block, 4 values
// (ParticleSet::F); the 9 of formats 1 and 2 still read.
// 4: digests of the file's bytes in its user block, checked before HDF5
// reads the file; formats 1 to 3 read without.
constexpr long kFormatVersion = 4;

// An HDF5 handle, closed by its own close function.
class Handle {
  public:
    Handle(hid_t id, herr_t (*closer)(hid_t)) : id_(id), close_(closer) {}
    ~Handle() {
        if (id_ >= 0) close_(id_);
    }
    Handle(Handle &&o) noexcept : id_(o.id_), close_(o.close_) { o.id_ = -1; }
    Handle(const Handle &) = delete;
    Handle &operator=(const Handle &) = delete;
    hid_t get() const { return id_; }
    bool ok() const { return id_ >= 0; }
    // Closes now, reporting whether it worked (a file's last writes).
    bool close() {
        const herr_t r = id_ >= 0 ? close_(id_) : 0;
        id_ = -1;
        return r >= 0;
    }

  private:
    hid_t id_;
    herr_t (*close_)(hid_t);
};

// The system's reason in HDF5's error stack ("errno = 28, error message =
// ..."), for a failed write: the disk full, a quota, a file-size limit.
std::string system_reason() {
    int found = 0;
    H5Ewalk2(
        H5E_DEFAULT, H5E_WALK_DOWNWARD,
        [](unsigned, const H5E_error2_t *e, void *out) -> herr_t {
            const char *at = e && e->desc ? std::strstr(e->desc, "errno = ") : nullptr;
            if (at) *static_cast<int *>(out) = std::atoi(at + 8);
            return at ? 1 : 0; // the first one, nearest the system call
        },
        &found);
    return found > 0 ? std::strerror(found) : std::string();
}

// HDF5 as this file uses it, set up before its first call. Without the
// library's exit handler: HDF5 1.10 keeps a file whose close failed (a
// write that found the disk full) in its table after freeing it, and its
// exit handler then crashed closing it again (fixed in HDF5 1.14, PR 2291).
// Every file here is closed by its Handle, so nothing is left for the
// handler to do.
void setup_hdf5() {
    static const bool once = [] { return H5dont_atexit() >= 0; }();
    (void)once;
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); // our messages, not HDF5's stack
}

// Reads and writes one file, every failure a talus::Error naming it.
class H5 {
  public:
    explicit H5(fs::path file) : file_(std::move(file)) { setup_hdf5(); }
    // With the system's reason where HDF5 met one.
    [[noreturn]] void fail(const std::string &what) const {
        const std::string why = system_reason();
        throw Error(fmt::format("{}: {}{}", file_.string(), what,
                                why.empty() ? std::string() : ": " + why));
    }
    hid_t check(hid_t id, const std::string &what) const {
        if (id < 0) fail(what);
        return id;
    }
    void check(herr_t r, const char *what, const std::string &name) const {
        if (r < 0) fail(fmt::format("{} '{}' failed", what, name));
    }

    // ---- text: short text (names, versions, hashes) as attributes, which
    // `h5dump -A` shows; text of any length (the scenario) as a dataset (an
    // attribute holds 64 kB at most).
    enum class As { attribute, dataset };
    void write_text(hid_t at, const std::string &name, const std::string &value, As as) const {
        const Handle type = string_type(std::max<std::size_t>(value.size(), 1), name);
        Handle space(check(H5Screate(H5S_SCALAR), "dataspace"), H5Sclose);
        const std::string padded = value.empty() ? std::string(1, '\0') : value;
        if (as == As::attribute) {
            Handle a(check(H5Acreate2(at, name.c_str(), type.get(), space.get(), H5P_DEFAULT,
                                      H5P_DEFAULT),
                           "cannot create the attribute " + name),
                     H5Aclose);
            check(H5Awrite(a.get(), type.get(), padded.data()), "writing the attribute", name);
        } else {
            Handle d(check(H5Dcreate2(at, name.c_str(), type.get(), space.get(), H5P_DEFAULT,
                                      H5P_DEFAULT, H5P_DEFAULT),
                           "cannot create the array " + name),
                     H5Dclose);
            check(H5Dwrite(d.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, padded.data()),
                  "writing the text", name);
        }
    }
    std::string read_text(hid_t at, const std::string &name, As as) const {
        const bool attr = as == As::attribute;
        Handle obj(check(attr ? H5Aopen(at, name.c_str(), H5P_DEFAULT)
                              : H5Dopen2(at, name.c_str(), H5P_DEFAULT),
                         "missing '" + name + "'"),
                   attr ? H5Aclose : H5Dclose);
        Handle type(check(attr ? H5Aget_type(obj.get()) : H5Dget_type(obj.get()), "text type"),
                    H5Tclose);
        if (H5Tget_class(type.get()) != H5T_STRING) fail("'" + name + "' is not text");
        const std::size_t n = H5Tget_size(type.get());
        std::string out(n, '\0');
        const Handle mem = string_type(n, name);
        check(attr ? H5Aread(obj.get(), mem.get(), out.data())
                   : H5Dread(obj.get(), mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()),
              "reading the text", name);
        out.resize(std::strlen(out.c_str()));
        return out;
    }
    void attr_string(hid_t at, const std::string &name, const std::string &value) const {
        write_text(at, name, value, As::attribute);
    }
    std::string read_attr_string(hid_t at, const std::string &name) const {
        return read_text(at, name, As::attribute);
    }

    // ---- numbers
    template <class T>
    void attr(hid_t at, const std::string &name, T value) const {
        Handle space(check(H5Screate(H5S_SCALAR), "dataspace"), H5Sclose);
        Handle a(
            check(H5Acreate2(at, name.c_str(), native<T>(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
                  "cannot create the attribute " + name),
            H5Aclose);
        check(H5Awrite(a.get(), native<T>(), &value), "writing the attribute", name);
    }
    void dataset(hid_t at, const std::string &name, hid_t type, const void *data, hsize_t rows,
                 hsize_t cols) const {
        const hsize_t dims[2] = {rows, cols};
        Handle space(check(H5Screate_simple(cols > 1 ? 2 : 1, dims, nullptr), "dataspace"),
                     H5Sclose);
        Handle d(check(H5Dcreate2(at, name.c_str(), type, space.get(), H5P_DEFAULT, H5P_DEFAULT,
                                  H5P_DEFAULT),
                       "cannot create the array " + name),
                 H5Dclose);
        if (rows * cols > 0)
            check(H5Dwrite(d.get(), type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "writing the array",
                  name);
    }
    Handle group(hid_t at, const std::string &name) const {
        return Handle(check(H5Gcreate2(at, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                            "cannot create the group " + name),
                      H5Gclose);
    }

    // ---- reading
    bool has(hid_t at, const std::string &name) const { return H5Aexists(at, name.c_str()) > 0; }
    template <class T>
    T read_attr(hid_t at, const std::string &name) const {
        Handle a(check(H5Aopen(at, name.c_str(), H5P_DEFAULT), "missing attribute '" + name + "'"),
                 H5Aclose);
        T value{};
        check(H5Aread(a.get(), native<T>(), &value), "reading the attribute", name);
        return value;
    }
    // The array `name` as `count` values of type `type`; its size must be
    // exactly that.
    void read_dataset(hid_t at, const std::string &name, hid_t type, void *data,
                      hsize_t count) const {
        Handle d(check(H5Dopen2(at, name.c_str(), H5P_DEFAULT), "missing array '" + name + "'"),
                 H5Dclose);
        Handle space(check(H5Dget_space(d.get()), "dataspace"), H5Sclose);
        const hssize_t n = H5Sget_simple_extent_npoints(space.get());
        if (n < 0 || static_cast<hsize_t>(n) != count)
            fail(fmt::format("the array '{}' holds {} values, {} expected", name, n, count));
        if (count > 0)
            check(H5Dread(d.get(), type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "reading the array",
                  name);
    }
    hsize_t dataset_size(hid_t at, const std::string &name) const {
        Handle d(check(H5Dopen2(at, name.c_str(), H5P_DEFAULT), "missing array '" + name + "'"),
                 H5Dclose);
        Handle space(check(H5Dget_space(d.get()), "dataspace"), H5Sclose);
        const hssize_t n = H5Sget_simple_extent_npoints(space.get());
        if (n < 0) fail("cannot read the size of '" + name + "'");
        return static_cast<hsize_t>(n);
    }
    Handle open_group(hid_t at, const std::string &name) const {
        return Handle(check(H5Gopen2(at, name.c_str(), H5P_DEFAULT),
                            "missing group '" + name + "' (not a complete checkpoint)"),
                      H5Gclose);
    }

    Handle string_type(std::size_t n, const std::string &name) const {
        Handle type(check(H5Tcopy(H5T_C_S1), "string type"), H5Tclose);
        check(H5Tset_size(type.get(), n), "sizing the text", name);
        return type;
    }

    template <class T>
    static hid_t native() {
        if constexpr (std::is_same_v<T, double>)
            return H5T_NATIVE_DOUBLE;
        else if constexpr (std::is_same_v<T, std::int64_t> || std::is_same_v<T, long>)
            return H5T_NATIVE_INT64;
        else if constexpr (std::is_same_v<T, std::int32_t> || std::is_same_v<T, int>)
            return H5T_NATIVE_INT32;
        else if constexpr (std::is_same_v<T, std::uint64_t>)
            return H5T_NATIVE_UINT64;
        else
            return H5T_NATIVE_UINT32;
    }

  private:
    fs::path file_;
};

hid_t column_type(Snapshot::Type t) {
    switch (t) {
    case Snapshot::Type::f64: return H5T_NATIVE_DOUBLE;
    case Snapshot::Type::i64: return H5T_NATIVE_INT64;
    case Snapshot::Type::i32: return H5T_NATIVE_INT32;
    case Snapshot::Type::u32: return H5T_NATIVE_UINT32;
    }
    return H5T_NATIVE_DOUBLE;
}

std::size_t type_size(Snapshot::Type t) {
    return t == Snapshot::Type::f64 || t == Snapshot::Type::i64 ? 8 : 4;
}

const char *type_name(Snapshot::Type t) {
    switch (t) {
    case Snapshot::Type::f64: return "f64";
    case Snapshot::Type::i64: return "i64";
    case Snapshot::Type::i32: return "i32";
    case Snapshot::Type::u32: return "u32";
    }
    return "f64";
}

Snapshot::Type type_named(const H5 &h5, const std::string &name) {
    for (Snapshot::Type t :
         {Snapshot::Type::f64, Snapshot::Type::i64, Snapshot::Type::i32, Snapshot::Type::u32})
        if (name == type_name(t)) return t;
    h5.fail("unknown column type '" + name + "'");
}

// fsync of a file or folder by path: the data and the rename reach the disk.
void sync_path(const fs::path &p, const H5 &h5) {
    const int fd = ::open(p.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) h5.fail(fmt::format("cannot open to sync: {}", std::strerror(errno)));
    const int r = ::fsync(fd);
    const int err = errno;
    ::close(fd);
    if (r != 0 && err != EINVAL)
        h5.fail(fmt::format("cannot sync to disk: {}", std::strerror(err)));
}

void write_state(const H5 &h5, hid_t root, const Snapshot &s) {
    h5.attr<long>(root, "step", s.step);
    h5.attr<double>(root, "time", s.time);
    h5.attr<double>(root, "last_dt", s.last_dt);
    h5.attr<double>(root, "max_speed", s.max_speed);
    h5.attr<long>(root, "removed", s.removed);
    h5.attr<long>(root, "held_at_faces", s.held_at_faces);
    h5.attr<long>(root, "cut_steps", s.cut_steps);
    h5.attr<double>(root, "held_depth", s.held_depth);
    h5.attr<int>(root, "warned_dt", s.warned_dt ? 1 : 0);
    h5.attr<long>(root, "stage", static_cast<long>(s.stage));
    h5.attr<double>(root, "stage_start", s.stage_start);
    h5.dataset(root, "gravity_before", H5T_NATIVE_DOUBLE, s.gravity_before.data(), 3, 1);
    if (s.hold) h5.attr<double>(root, "hold", *s.hold);
    if (s.below_since) h5.attr<double>(root, "below_since", *s.below_since);
    h5.attr<double>(root, "kinetic_energy_ratio", s.ratio);
    h5.attr<double>(root, "out_of_order", s.out_of_order);
    h5.attr<int>(root, "slabs_changed", s.slabs_changed ? 1 : 0);
    h5.attr<int>(root, "batch_size", s.batch_size);
    h5.attr<double>(root, "sort_disorder", s.sort_disorder);
    if (!s.boxes.empty()) {
        h5.attr<int>(root, "rank", s.rank);
        h5.dataset(root, "cell_boxes", H5T_NATIVE_INT32, s.boxes.data(), s.boxes.size(), 6);
    }
    Handle sets = h5.group(root, "sets");
    for (std::size_t k = 0; k < s.sets.size(); ++k) {
        const Snapshot::Set &set = s.sets[k];
        Handle g = h5.group(sets.get(), std::to_string(k));
        h5.attr<long>(g.get(), "material", static_cast<long>(set.material));
        h5.attr<long>(g.get(), "n", static_cast<long>(set.n));
        std::string order;
        for (const Snapshot::Column &c : set.columns) {
            h5.dataset(g.get(), c.name, column_type(c.type), c.bytes.data(), set.n, c.stride);
            Handle d(h5.check(H5Dopen2(g.get(), c.name.c_str(), H5P_DEFAULT), "array"), H5Dclose);
            h5.attr_string(d.get(), "type", type_name(c.type));
            h5.attr<long>(d.get(), "per_particle", static_cast<long>(c.stride));
            if (!order.empty()) order += ',';
            order += c.name;
        }
        h5.attr_string(g.get(), "columns", order); // their order in the set
        h5.dataset(g.get(), "slab_of", H5T_NATIVE_INT32, set.slab_of.data(), set.slab_of.size(), 1);
    }
}

Snapshot read_state(const H5 &h5, hid_t root) {
    Snapshot s;
    s.step = h5.read_attr<long>(root, "step");
    s.time = h5.read_attr<double>(root, "time");
    s.last_dt = h5.read_attr<double>(root, "last_dt");
    s.max_speed = h5.read_attr<double>(root, "max_speed");
    s.removed = h5.read_attr<long>(root, "removed");
    s.held_at_faces = h5.read_attr<long>(root, "held_at_faces");
    s.cut_steps = h5.read_attr<long>(root, "cut_steps");
    s.held_depth = h5.read_attr<double>(root, "held_depth");
    s.warned_dt = h5.read_attr<int>(root, "warned_dt") != 0;
    s.stage = static_cast<std::size_t>(h5.read_attr<long>(root, "stage"));
    s.stage_start = h5.read_attr<double>(root, "stage_start");
    h5.read_dataset(root, "gravity_before", H5T_NATIVE_DOUBLE, s.gravity_before.data(), 3);
    if (h5.has(root, "hold")) s.hold = h5.read_attr<double>(root, "hold");
    if (h5.has(root, "below_since")) s.below_since = h5.read_attr<double>(root, "below_since");
    s.ratio = h5.read_attr<double>(root, "kinetic_energy_ratio");
    s.out_of_order = h5.read_attr<double>(root, "out_of_order");
    s.slabs_changed = h5.read_attr<int>(root, "slabs_changed") != 0;
    s.batch_size = h5.read_attr<int>(root, "batch_size");
    s.sort_disorder = h5.read_attr<double>(root, "sort_disorder");
    if (H5Lexists(root, "cell_boxes", H5P_DEFAULT) > 0) {
        s.rank = h5.read_attr<int>(root, "rank");
        s.boxes.resize(h5.dataset_size(root, "cell_boxes") / 6);
        h5.read_dataset(root, "cell_boxes", H5T_NATIVE_INT32, s.boxes.data(), s.boxes.size() * 6);
        if (s.boxes.size() < 2 || s.rank < 0 || static_cast<std::size_t>(s.rank) >= s.boxes.size())
            h5.fail(fmt::format("rank {} of {}: not a rank of a run on several", s.rank,
                                s.boxes.size()));
    }
    Handle sets = h5.open_group(root, "sets");
    for (std::size_t k = 0;; ++k) {
        if (H5Lexists(sets.get(), std::to_string(k).c_str(), H5P_DEFAULT) <= 0) break;
        Handle g = h5.open_group(sets.get(), std::to_string(k));
        Snapshot::Set set;
        set.material = static_cast<std::size_t>(h5.read_attr<long>(g.get(), "material"));
        const long n = h5.read_attr<long>(g.get(), "n");
        if (n < 0) h5.fail(fmt::format("set {} has {} particles", k, n));
        set.n = static_cast<std::size_t>(n);
        const std::string order = h5.read_attr_string(g.get(), "columns");
        for (std::size_t a = 0; a <= order.size();) {
            std::size_t b = order.find(',', a);
            if (b == std::string::npos) b = order.size();
            Snapshot::Column c;
            c.name = order.substr(a, b - a);
            a = b + 1;
            if (c.name.empty()) continue;
            Handle d(h5.check(H5Dopen2(g.get(), c.name.c_str(), H5P_DEFAULT),
                              "missing array '" + c.name + "'"),
                     H5Dclose);
            c.type = type_named(h5, h5.read_attr_string(d.get(), "type"));
            const long stride = h5.read_attr<long>(d.get(), "per_particle");
            if (stride < 1 || stride > 1 << 20)
                h5.fail(fmt::format("the array '{}' has {} values per particle", c.name, stride));
            c.stride = static_cast<std::size_t>(stride);
            c.bytes.resize(set.n * c.stride * type_size(c.type));
            h5.read_dataset(g.get(), c.name, column_type(c.type), c.bytes.data(), set.n * c.stride);
            set.columns.push_back(std::move(c));
        }
        set.slab_of.resize(h5.dataset_size(g.get(), "slab_of"));
        h5.read_dataset(g.get(), "slab_of", H5T_NATIVE_INT32, set.slab_of.data(),
                        set.slab_of.size());
        s.sets.push_back(std::move(set));
    }
    return s;
}

} // namespace

std::string describe(const PluginIdentity &p) {
    return fmt::format("talus: material '{}': model '{}' {} from {} (library {}, SHA-256 {})",
                       p.material, p.qualified_id, p.model_version, p.path, p.library_version,
                       p.sha256);
}

std::vector<PluginIdentity> plugin_identities(const Scenario &sc) {
    std::vector<PluginIdentity> out;
    for (const NamedMaterial &m : sc.materials) {
        const Model &model = *m.spec.model;
        const PluginLibrary &lib = model.library();
        out.push_back({m.name, model.qualified_id(), lib.path().string(), lib.version(),
                       model.version(), lib.content_hash(), static_cast<int>(lib.abi_major()),
                       static_cast<int>(lib.abi_minor())});
    }
    return out;
}

std::vector<std::string> identity_differences(const Checkpoint &c,
                                              const std::vector<PluginIdentity> &now) {
    std::vector<std::string> diff;
    if (c.talus_version != TALUS_VERSION_STRING)
        diff.push_back(fmt::format("Talus {} wrote the checkpoint, this is Talus {}",
                                   c.talus_version, TALUS_VERSION_STRING));
    if (c.abi_major != TALUS_ABI_VERSION_MAJOR || c.abi_minor != TALUS_ABI_VERSION_MINOR)
        diff.push_back(fmt::format("the checkpoint's plugin ABI is {}.{}, this Talus's {}.{}",
                                   c.abi_major, c.abi_minor, TALUS_ABI_VERSION_MAJOR,
                                   TALUS_ABI_VERSION_MINOR));
    if (c.plugins.size() != now.size()) {
        diff.push_back(fmt::format("the checkpoint has {} materials, the scenario now {}",
                                   c.plugins.size(), now.size()));
        return diff;
    }
    for (std::size_t k = 0; k < now.size(); ++k) {
        const PluginIdentity &a = c.plugins[k], &b = now[k];
        const std::string who = fmt::format("material '{}'", b.material);
        auto differ = [&](const char *what, const std::string &then, const std::string &here) {
            if (then != here)
                diff.push_back(fmt::format("{}: {} was {}, is now {}", who, what, then, here));
        };
        differ("the material's name", a.material, b.material);
        differ("the model", a.qualified_id, b.qualified_id);
        differ("the plugin file", a.path, b.path);
        differ("the library version", a.library_version, b.library_version);
        differ("the model version", a.model_version, b.model_version);
        differ("the plugin's SHA-256", a.sha256, b.sha256);
        differ("the plugin's ABI", fmt::format("{}.{}", a.abi_major, a.abi_minor),
               fmt::format("{}.{}", b.abi_major, b.abi_minor));
    }
    return diff;
}

void write_checkpoint(const fs::path &file, const Checkpoint &c) {
    const fs::path tmp = file.parent_path() / fmt::format(".{}.tmp", file.filename().string());
    const H5 h5(file);
    // The user block holds a line per array (docs/restart.md).
    std::size_t arrays = 8, names = 64;
    for (std::size_t k = 0; k < c.state.sets.size(); ++k) {
        arrays += c.state.sets[k].columns.size() + 1;
        for (const Snapshot::Column &col : c.state.sets[k].columns)
            names += col.name.size() + 24;
        names += 32;
    }
    const std::size_t userblock = checkpoint_digests::userblock_size(arrays, names);
    std::vector<checkpoint_digests::Range> stored;
    {
        Handle fcpl(h5.check(H5Pcreate(H5P_FILE_CREATE), "file creation properties"), H5Pclose);
        h5.check(H5Pset_userblock(fcpl.get(), userblock), "setting the user block", "");
        Handle f(h5.check(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT),
                          "cannot create the checkpoint's temporary file " + tmp.string()),
                 H5Fclose);
        try {
            const hid_t root = f.get();
            h5.attr_string(root, "format", kFormat);
            h5.attr<long>(root, "format_version", kFormatVersion);
            // The binaries writing it, whatever `c` says.
            h5.attr_string(root, "talus_version", TALUS_VERSION_STRING);
            h5.attr<int>(root, "abi_major", TALUS_ABI_VERSION_MAJOR);
            h5.attr<int>(root, "abi_minor", TALUS_ABI_VERSION_MINOR);
            h5.attr_string(root, "run_id", c.run_id);
            {
                Handle sc = h5.group(root, "scenario");
                h5.attr_string(sc.get(), "path", c.scenario_path);
                h5.attr_string(sc.get(), "sha256", c.scenario_sha256);
                h5.write_text(sc.get(), "text", c.scenario_text, H5::As::dataset);
            }
            {
                Handle pl = h5.group(root, "plugins");
                for (std::size_t k = 0; k < c.plugins.size(); ++k) {
                    const PluginIdentity &p = c.plugins[k];
                    Handle g = h5.group(pl.get(), std::to_string(k));
                    h5.attr_string(g.get(), "material", p.material);
                    h5.attr_string(g.get(), "model", p.qualified_id);
                    h5.attr_string(g.get(), "path", p.path);
                    h5.attr_string(g.get(), "library_version", p.library_version);
                    h5.attr_string(g.get(), "model_version", p.model_version);
                    h5.attr_string(g.get(), "sha256", p.sha256);
                    h5.attr<int>(g.get(), "abi_major", p.abi_major);
                    h5.attr<int>(g.get(), "abi_minor", p.abi_minor);
                }
            }
            {
                const OutputProgress &o = c.output;
                Handle g = h5.group(root, "output");
                h5.attr<long>(g.get(), "next_output", o.next_output);
                h5.attr<long>(g.get(), "next_due", o.next_due);
                h5.attr<long>(g.get(), "last_written_step", o.last_written_step);
                h5.attr<long>(g.get(), "stage_first_step", o.stage_first_step);
                h5.attr<long>(g.get(), "particle_steps", o.particle_steps);
                h5.attr<std::uint64_t>(g.get(), "diagnostics_bytes", o.diagnostics_bytes);
                h5.attr<std::uint64_t>(g.get(), "probes_bytes", o.probes_bytes);
                h5.attr<std::uint64_t>(g.get(), "stages_bytes", o.stages_bytes);
                h5.dataset(g.get(), "frames", H5T_NATIVE_DOUBLE, o.frames.data(), o.frames.size(),
                           1);
                h5.dataset(g.get(), "probe_particles", H5T_NATIVE_INT64, o.probe_particles.data(),
                           o.probe_particles.size(), 1);
            }
            write_state(h5, root, c.state);
            try {
                stored = checkpoint_digests::arrays(root);
            } catch (const Error &e) {
                h5.fail(e.what());
            }
            if (H5Fflush(root, H5F_SCOPE_GLOBAL) < 0) h5.fail("cannot flush the checkpoint");
            if (!f.close()) h5.fail("cannot close the checkpoint (the disk may be full)");
        } catch (...) {
            f.close();
            ::unlink(tmp.c_str());
            throw;
        }
    }
    try {
        checkpoint_digests::seal(tmp, userblock, stored);
    } catch (const Error &e) {
        ::unlink(tmp.c_str());
        h5.fail(fmt::format("cannot write the checkpoint's digests: {}", e.what()));
    }
    sync_path(tmp, h5);
    if (::rename(tmp.c_str(), file.c_str()) != 0) {
        const int err = errno;
        ::unlink(tmp.c_str());
        h5.fail(
            fmt::format("cannot move the finished checkpoint into place: {}", std::strerror(err)));
    }
    sync_path(file.parent_path().empty() ? fs::path(".") : file.parent_path(), h5);
}

Checkpoint read_checkpoint(const fs::path &file) {
    const H5 h5(file);
    if (!fs::exists(file)) h5.fail("no such file");
    if (const std::string why = not_a_regular_file(file); !why.empty()) h5.fail(why);
    // Checked on the raw bytes first: HDF5 never parses a damaged file, and
    // no damaged value (the format's version included) decides what is read.
    const bool sealed = checkpoint_digests::sealed(file);
    if (sealed)
        if (const auto damage = checkpoint_digests::damage(file))
            h5.fail(fmt::format("the checkpoint is damaged: {}; it cannot be trusted (restart "
                                "from another checkpoint)",
                                *damage));
    if (H5Fis_hdf5(file.c_str()) <= 0) h5.fail("not an HDF5 file (not a Talus checkpoint)");
    Handle f(h5.check(H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), "cannot open"), H5Fclose);
    const hid_t root = f.get();
    if (!h5.has(root, "format") || h5.read_attr_string(root, "format") != kFormat)
        h5.fail("an HDF5 file, but not a Talus checkpoint");
    const long version = h5.read_attr<long>(root, "format_version");
    if (version < 1 || version > kFormatVersion)
        h5.fail(fmt::format("checkpoint format {}; this Talus reads formats 1 to {}", version,
                            kFormatVersion));
    if (version >= 4 && !sealed)
        h5.fail("the checkpoint is damaged: it has no digest table (format 4 and later have one "
                "at the start of the file)");
    Checkpoint c;
    c.talus_version = h5.read_attr_string(root, "talus_version");
    c.abi_major = h5.read_attr<int>(root, "abi_major");
    c.abi_minor = h5.read_attr<int>(root, "abi_minor");
    // Format 4 files of the first builds to write it carry no run id: a run
    // of no name, checked by its digests (run_folder.hpp).
    if (h5.has(root, "run_id")) c.run_id = h5.read_attr_string(root, "run_id");
    {
        Handle sc = h5.open_group(root, "scenario");
        c.scenario_path = h5.read_attr_string(sc.get(), "path");
        c.scenario_sha256 = h5.read_attr_string(sc.get(), "sha256");
        c.scenario_text = h5.read_text(sc.get(), "text", H5::As::dataset);
    }
    {
        Handle pl = h5.open_group(root, "plugins");
        for (std::size_t k = 0; H5Lexists(pl.get(), std::to_string(k).c_str(), H5P_DEFAULT) > 0;
             ++k) {
            Handle g = h5.open_group(pl.get(), std::to_string(k));
            PluginIdentity p;
            p.material = h5.read_attr_string(g.get(), "material");
            p.qualified_id = h5.read_attr_string(g.get(), "model");
            p.path = h5.read_attr_string(g.get(), "path");
            p.library_version = h5.read_attr_string(g.get(), "library_version");
            p.model_version = h5.read_attr_string(g.get(), "model_version");
            p.sha256 = h5.read_attr_string(g.get(), "sha256");
            p.abi_major = h5.read_attr<int>(g.get(), "abi_major");
            p.abi_minor = h5.read_attr<int>(g.get(), "abi_minor");
            c.plugins.push_back(std::move(p));
        }
    }
    {
        OutputProgress &o = c.output;
        Handle g = h5.open_group(root, "output");
        o.next_output = h5.read_attr<long>(g.get(), "next_output");
        o.next_due = h5.read_attr<long>(g.get(), "next_due");
        o.last_written_step = h5.read_attr<long>(g.get(), "last_written_step");
        o.stage_first_step = h5.read_attr<long>(g.get(), "stage_first_step");
        o.particle_steps = h5.read_attr<long>(g.get(), "particle_steps");
        o.diagnostics_bytes = h5.read_attr<std::uint64_t>(g.get(), "diagnostics_bytes");
        o.probes_bytes = h5.read_attr<std::uint64_t>(g.get(), "probes_bytes");
        o.stages_bytes = h5.read_attr<std::uint64_t>(g.get(), "stages_bytes");
        o.frames.resize(h5.dataset_size(g.get(), "frames"));
        h5.read_dataset(g.get(), "frames", H5T_NATIVE_DOUBLE, o.frames.data(), o.frames.size());
        o.probe_particles.resize(h5.dataset_size(g.get(), "probe_particles"));
        h5.read_dataset(g.get(), "probe_particles", H5T_NATIVE_INT64, o.probe_particles.data(),
                        o.probe_particles.size());
    }
    c.state = read_state(h5, root);
    return c;
}

fs::path rank_checkpoint_file(const fs::path &file, int rank) {
    if (rank == 0) return file;
    return file.parent_path() / fmt::format("{}.rank{:04d}.h5", file.stem().string(), rank);
}

Checkpoint read_checkpoint_for(const fs::path &file, int rank, int ranks) {
    Checkpoint c = read_checkpoint(file);
    // What every rank's file must share with rank 0's (kept apart: rank
    // 0's state moves into the merged one below).
    struct {
        long step;
        int rank;
        std::vector<std::array<int, 6>> boxes;
        std::size_t sets;
    } const first{c.state.step, c.state.rank, c.state.boxes, c.state.sets.size()};
    if (!first.boxes.empty() && first.rank != 0) {
        const std::string stem = file.stem().string();
        throw Error(fmt::format(
            "{}: the part of rank {} of a checkpoint written by {} ranks; "
            "restart from rank 0's file, {}",
            file.string(), first.rank, first.boxes.size(),
            (file.parent_path() / (stem.substr(0, stem.rfind(".rank")) + ".h5")).string()));
    }
    const int written = std::max<int>(1, static_cast<int>(first.boxes.size()));
    // Rank r's file, there.
    auto existing = [&](int r) {
        fs::path f = rank_checkpoint_file(file, r);
        if (!fs::exists(f))
            throw Error(fmt::format("{}: missing: the checkpoint {} was written by {} ranks, each "
                                    "into its own file",
                                    f.string(), file.string(), written));
        return f;
    };
    // Another rank's file of the same run and step.
    auto part = [&](int r) {
        const fs::path f = existing(r);
        Checkpoint k = read_checkpoint(f);
        if (k.state.step != first.step || k.state.rank != r || k.state.boxes != first.boxes ||
            k.scenario_sha256 != c.scenario_sha256 || k.run_id != c.run_id ||
            k.state.sets.size() != first.sets)
            throw Error(fmt::format("{}: not rank {}'s part of {} (another step or run)",
                                    f.string(), r, file.string()));
        return k;
    };
    if (written == ranks) {
        if (rank != 0) c.state = part(rank).state;
        return c;
    }
    // Another number of ranks: this rank reads its share of the files
    // (a contiguous run of them; none when there are fewer files than
    // ranks), so that no rank holds every particle; the solver sends the
    // particles to their cells' ranks. The ordering marks are dropped (the
    // solver orders anew); the cut steps of the files read are summed (the
    // run's count is the sum over the ranks).
    for (int r = 1; r < written; ++r) // every file there, whoever reads it
        existing(r);
    // File f goes to rank f ranks / written: files [lo, hi) here.
    const auto first_file = [&](long r) {
        return static_cast<int>((r * written + ranks - 1) / ranks);
    };
    const int lo = first_file(rank), hi = first_file(rank + 1);
    const bool reads_first = lo == 0 && hi > 0;
    Snapshot all = std::move(c.state);
    all.rank = 0;
    all.boxes.clear();
    for (Snapshot::Set &set : all.sets) {
        set.slab_of.clear();
        if (!reads_first) { // rank 0's particles are another rank's share
            set.n = 0;
            for (Snapshot::Column &col : set.columns)
                col.bytes.clear();
        }
    }
    if (!reads_first) all.cut_steps = 0;
    all.slabs_changed = true;
    for (int r = std::max(lo, 1); r < hi; ++r) {
        const Snapshot s = part(r).state;
        all.cut_steps += s.cut_steps;
        for (std::size_t k = 0; k < all.sets.size(); ++k) {
            Snapshot::Set &to = all.sets[k];
            const Snapshot::Set &from = s.sets[k];
            if (from.material != to.material || from.columns.size() != to.columns.size())
                throw Error(fmt::format("{}: its particle set {} differs from rank 0's",
                                        rank_checkpoint_file(file, r).string(), k));
            for (std::size_t j = 0; j < to.columns.size(); ++j) {
                const Snapshot::Column &a = from.columns[j];
                Snapshot::Column &b = to.columns[j];
                if (a.name != b.name || a.type != b.type || a.stride != b.stride)
                    throw Error(fmt::format("{}: its particle set {} has the column '{}' where "
                                            "rank 0's has '{}'",
                                            rank_checkpoint_file(file, r).string(), k, a.name,
                                            b.name));
                b.bytes.insert(b.bytes.end(), a.bytes.begin(), a.bytes.end());
            }
            to.n += from.n;
        }
    }
    c.state = std::move(all);
    return c;
}

} // namespace talus
