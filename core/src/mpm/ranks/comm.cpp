#include <talus/error.hpp>
#include <talus/mpm/comm.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <climits>
#include <cstdlib>
#include <cstring>

#ifdef TALUS_HAVE_MPI
#include <mpi.h>
#endif

namespace talus {

#ifdef TALUS_HAVE_MPI

struct Comm::Handle {
    MPI_Comm comm;
};

namespace {

// An MPI call that fails ends the run with MPI's message: with the default
// error handler (MPI_ERRORS_ARE_FATAL) it never returns, but a launcher may
// set another.
void check(int rc, const char *what) {
    if (rc == MPI_SUCCESS) return;
    char text[MPI_MAX_ERROR_STRING];
    int len = 0;
    MPI_Error_string(rc, text, &len);
    throw Error(
        fmt::format("MPI: {} failed: {}", what, std::string(text, static_cast<std::size_t>(len))));
}

int count_of(std::size_t n) {
    if (n > static_cast<std::size_t>(INT_MAX))
        throw Error(fmt::format("MPI: a message of {} bytes is above MPI's int count", n));
    return static_cast<int>(n);
}

MPI_Comm raw(const std::shared_ptr<const Comm::Handle> &h) { return h->comm; }

} // namespace

Comm Comm::world() {
    int init = 0, fin = 0;
    MPI_Initialized(&init);
    MPI_Finalized(&fin);
    if (!init || fin) return serial();
    Comm c;
    c.handle_ = std::make_shared<const Handle>(Handle{MPI_COMM_WORLD});
    MPI_Comm_rank(MPI_COMM_WORLD, &c.rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &c.size_);
    return c;
}

bool Comm::built_with_mpi() { return true; }

#define TALUS_MPI_OR(serial_result)                                                                \
    if (!distributed()) return serial_result

namespace {

MPI_Datatype mpi_type(const double *) { return MPI_DOUBLE; }
MPI_Datatype mpi_type(const long *) { return MPI_LONG; }

// Every rank's n values combined by `op`, in place.
template <class T>
void all_reduce(T *v, std::size_t n, MPI_Op op, MPI_Comm comm) {
    check(MPI_Allreduce(MPI_IN_PLACE, v, count_of(n), mpi_type(v), op, comm), "MPI_Allreduce");
}

} // namespace

double Comm::max(double v) const {
    TALUS_MPI_OR(v);
    all_reduce(&v, 1, MPI_MAX, raw(handle_));
    return v;
}

double Comm::min(double v) const {
    TALUS_MPI_OR(v);
    all_reduce(&v, 1, MPI_MIN, raw(handle_));
    return v;
}

double Comm::sum(double v) const {
    TALUS_MPI_OR(v);
    all_reduce(&v, 1, MPI_SUM, raw(handle_));
    return v;
}

long Comm::sum(long v) const {
    TALUS_MPI_OR(v);
    all_reduce(&v, 1, MPI_SUM, raw(handle_));
    return v;
}

void Comm::sum(double *v, std::size_t n) const {
    TALUS_MPI_OR();
    all_reduce(v, n, MPI_SUM, raw(handle_));
}

void Comm::sum(long *v, std::size_t n) const {
    TALUS_MPI_OR();
    all_reduce(v, n, MPI_SUM, raw(handle_));
}

void Comm::max(double *v, std::size_t n) const {
    TALUS_MPI_OR();
    all_reduce(v, n, MPI_MAX, raw(handle_));
}

void Comm::min(double *v, std::size_t n) const {
    TALUS_MPI_OR();
    all_reduce(v, n, MPI_MIN, raw(handle_));
}

std::vector<std::vector<std::byte>> Comm::exchange(const std::vector<int> &peers,
                                                   const std::vector<std::vector<std::byte>> &send,
                                                   int tag) const {
    std::vector<std::vector<std::byte>> recv(peers.size());
    if (!distributed() || peers.empty()) return recv;
    // Sizes first, so that each receive is posted with its length.
    const std::size_t n = peers.size();
    std::vector<unsigned long> out_size(n), in_size(n);
    std::vector<MPI_Request> req(2 * n);
    for (std::size_t k = 0; k < n; ++k) {
        out_size[k] = send[k].size();
        check(MPI_Irecv(&in_size[k], 1, MPI_UNSIGNED_LONG, peers[k], tag, raw(handle_), &req[k]),
              "MPI_Irecv");
        check(
            MPI_Isend(&out_size[k], 1, MPI_UNSIGNED_LONG, peers[k], tag, raw(handle_), &req[n + k]),
            "MPI_Isend");
    }
    check(MPI_Waitall(static_cast<int>(2 * n), req.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
    for (std::size_t k = 0; k < n; ++k) {
        recv[k].resize(in_size[k]);
        check(MPI_Irecv(recv[k].data(), count_of(in_size[k]), MPI_BYTE, peers[k], tag + 1,
                        raw(handle_), &req[k]),
              "MPI_Irecv");
        check(MPI_Isend(send[k].data(), count_of(send[k].size()), MPI_BYTE, peers[k], tag + 1,
                        raw(handle_), &req[n + k]),
              "MPI_Isend");
    }
    check(MPI_Waitall(static_cast<int>(2 * n), req.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
    return recv;
}

std::vector<std::vector<std::byte>>
Comm::all_to_all(const std::vector<std::vector<std::byte>> &send) const {
    if (!distributed()) return send;
    const std::size_t n = static_cast<std::size_t>(size_);
    std::vector<unsigned long> out_size(n), in_size(n);
    for (std::size_t r = 0; r < n; ++r)
        out_size[r] = send[r].size();
    check(MPI_Alltoall(out_size.data(), 1, MPI_UNSIGNED_LONG, in_size.data(), 1, MPI_UNSIGNED_LONG,
                       raw(handle_)),
          "MPI_Alltoall");
    std::vector<std::vector<std::byte>> recv(n);
    std::vector<MPI_Request> req;
    req.reserve(2 * n);
    for (std::size_t r = 0; r < n; ++r) {
        recv[r].resize(in_size[r]);
        if (in_size[r] > 0) {
            req.emplace_back();
            check(MPI_Irecv(recv[r].data(), count_of(in_size[r]), MPI_BYTE, static_cast<int>(r),
                            7001, raw(handle_), &req.back()),
                  "MPI_Irecv");
        }
        if (out_size[r] > 0) {
            req.emplace_back();
            check(MPI_Isend(send[r].data(), count_of(out_size[r]), MPI_BYTE, static_cast<int>(r),
                            7001, raw(handle_), &req.back()),
                  "MPI_Isend");
        }
    }
    check(MPI_Waitall(static_cast<int>(req.size()), req.data(), MPI_STATUSES_IGNORE),
          "MPI_Waitall");
    return recv;
}

std::vector<std::vector<std::byte>> Comm::gather(const std::vector<std::byte> &mine) const {
    if (!distributed()) return {mine};
    const std::size_t n = static_cast<std::size_t>(size_);
    unsigned long my_size = mine.size();
    std::vector<unsigned long> sizes(n);
    check(MPI_Gather(&my_size, 1, MPI_UNSIGNED_LONG, sizes.data(), 1, MPI_UNSIGNED_LONG, 0,
                     raw(handle_)),
          "MPI_Gather");
    std::vector<std::vector<std::byte>> out;
    if (rank_ == 0) {
        out.resize(n);
        out[0] = mine;
        std::vector<MPI_Request> req(n - 1);
        for (std::size_t r = 1; r < n; ++r) {
            out[r].resize(sizes[r]);
            check(MPI_Irecv(out[r].data(), count_of(sizes[r]), MPI_BYTE, static_cast<int>(r), 7002,
                            raw(handle_), &req[r - 1]),
                  "MPI_Irecv");
        }
        check(MPI_Waitall(static_cast<int>(n - 1), req.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
    } else {
        check(MPI_Send(mine.data(), count_of(mine.size()), MPI_BYTE, 0, 7002, raw(handle_)),
              "MPI_Send");
    }
    return out;
}

std::vector<std::byte> Comm::broadcast(std::vector<std::byte> bytes, int root) const {
    if (!distributed()) return bytes;
    unsigned long size = bytes.size();
    check(MPI_Bcast(&size, 1, MPI_UNSIGNED_LONG, root, raw(handle_)), "MPI_Bcast");
    bytes.resize(size);
    check(MPI_Bcast(bytes.data(), count_of(size), MPI_BYTE, root, raw(handle_)), "MPI_Bcast");
    return bytes;
}

std::optional<Comm::Failure> Comm::first_failure(const std::string *mine) const {
    if (!distributed()) {
        if (!mine) return std::nullopt;
        return Failure{0, *mine};
    }
    int candidate = mine ? rank_ : size_, first = size_;
    check(MPI_Allreduce(&candidate, &first, 1, MPI_INT, MPI_MIN, raw(handle_)), "MPI_Allreduce");
    if (first == size_) return std::nullopt;
    std::vector<std::byte> text;
    if (first == rank_) {
        text.resize(mine->size());
        std::memcpy(text.data(), mine->data(), mine->size());
    }
    text = broadcast(std::move(text), first);
    return Failure{first, std::string(reinterpret_cast<const char *>(text.data()), text.size())};
}

void Comm::barrier() const {
    TALUS_MPI_OR();
    check(MPI_Barrier(raw(handle_)), "MPI_Barrier");
}

#undef TALUS_MPI_OR

MpiSession::MpiSession(int *argc, char ***argv) {
    int init = 0;
    MPI_Initialized(&init);
    if (init) return;
    int provided = 0;
    // FUNNELED: only the main thread calls MPI, between the OpenMP loops.
    if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
        throw Error("MPI: MPI_Init_thread failed");
    owner_ = true;
}

MpiSession::~MpiSession() {
    if (owner_) MPI_Finalize();
}

void MpiSession::abort(int code) {
    int init = 0, fin = 0;
    MPI_Initialized(&init);
    MPI_Finalized(&fin);
    if (init && !fin) MPI_Abort(MPI_COMM_WORLD, code);
    std::exit(code);
}

#else // no MPI in this build: one rank

struct Comm::Handle {};

Comm Comm::world() { return serial(); }
bool Comm::built_with_mpi() { return false; }
double Comm::max(double v) const { return v; }
double Comm::sum(double v) const { return v; }
long Comm::sum(long v) const { return v; }
void Comm::sum(double *, std::size_t) const {}
void Comm::sum(long *, std::size_t) const {}
void Comm::max(double *, std::size_t) const {}
double Comm::min(double v) const { return v; }
void Comm::min(double *, std::size_t) const {}
std::vector<std::vector<std::byte>> Comm::exchange(const std::vector<int> &peers,
                                                   const std::vector<std::vector<std::byte>> &,
                                                   int) const {
    return std::vector<std::vector<std::byte>>(peers.size());
}
std::vector<std::vector<std::byte>>
Comm::all_to_all(const std::vector<std::vector<std::byte>> &send) const {
    return send;
}
std::vector<std::vector<std::byte>> Comm::gather(const std::vector<std::byte> &mine) const {
    return {mine};
}
std::vector<std::byte> Comm::broadcast(std::vector<std::byte> bytes, int) const { return bytes; }
std::optional<Comm::Failure> Comm::first_failure(const std::string *mine) const {
    if (!mine) return std::nullopt;
    return Failure{0, *mine};
}
void Comm::barrier() const {}
MpiSession::MpiSession(int *, char ***) {}
MpiSession::~MpiSession() = default;
void MpiSession::abort(int code) { std::exit(code); }

#endif

Comm Comm::serial() { return Comm{}; }

void Comm::agree(std::exception_ptr error) const {
    if (!distributed()) {
        if (error) std::rethrow_exception(error);
        return;
    }
    std::string message;
    if (error) {
        try {
            std::rethrow_exception(error);
        } catch (const std::exception &e) {
            message = e.what();
        } catch (...) {
            message = "an unknown exception";
        }
    }
    if (const std::optional<Failure> first = first_failure(error ? &message : nullptr))
        throw AgreedError(first->message);
}

int MpiSession::launched_ranks() {
    for (const char *var : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE", "SLURM_NTASKS"})
        if (const char *n = std::getenv(var))
            if (const int k = std::atoi(n); k > 0) return k;
    return 1;
}

} // namespace talus
