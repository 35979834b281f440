// The ranks a run is spread over (docs/mpi.md): the one place the core
// talks to MPI. A run on one rank, or a build without MPI, has the serial
// communicator, whose collectives return their argument: the solver's
// serial path calls none of them.
#pragma once

#include <talus/error.hpp>

#include <cstddef>
#include <exception>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace talus {

class Comm {
  public:
    // One rank (no MPI call is ever made through it).
    static Comm serial();
    // MPI_COMM_WORLD; the serial communicator when MPI is not initialised
    // or the build has none.
    static Comm world();
    // Whether this build has MPI.
    static bool built_with_mpi();

    int rank() const { return rank_; }
    int size() const { return size_; }
    bool distributed() const { return size_ > 1; }

    // Reductions over all ranks (collective: every rank calls them in the
    // same order). MPI's reductions are deterministic for a given rank
    // count (Open MPI's for a given count and message size), so every rank
    // gets the same bits.
    double max(double v) const;
    double sum(double v) const;
    long sum(long v) const;
    void sum(double *v, std::size_t n) const;
    void sum(long *v, std::size_t n) const;
    void max(double *v, std::size_t n) const;
    double min(double v) const;
    void min(double *v, std::size_t n) const;

    // Sends bytes to each of `peers` and receives from each of them
    // (collective among the peers: each rank lists the ranks it exchanges
    // with, symmetrically; an empty buffer is sent too). Returns what came
    // from peers[k] in [k].
    std::vector<std::vector<std::byte>> exchange(const std::vector<int> &peers,
                                                 const std::vector<std::vector<std::byte>> &send,
                                                 int tag) const;
    // Every rank sends send[r] to rank r (collective).
    std::vector<std::vector<std::byte>>
    all_to_all(const std::vector<std::vector<std::byte>> &send) const;
    // Rank 0 receives every rank's bytes in rank order; the others get an
    // empty vector (collective).
    std::vector<std::vector<std::byte>> gather(const std::vector<std::byte> &mine) const;
    // The same bytes on every rank, from `root` (collective).
    std::vector<std::byte> broadcast(std::vector<std::byte> bytes, int root) const;

    // A failure on some rank (collective): each rank says whether it has
    // failed, with its message. Returns, on every rank, the lowest failed
    // rank and its message; nothing when none failed.
    struct Failure {
        int rank = 0;
        std::string message;
    };
    std::optional<Failure> first_failure(const std::string *mine) const;
    // Whether any rank failed (collective): each passes its error or null.
    // On one rank, rethrows its own; on several, every rank throws
    // AgreedError with the lowest failed rank's message when any failed,
    // so that no rank goes on to a collective the others never reach.
    void agree(std::exception_ptr error) const;

    void barrier() const;

    struct Handle; // the MPI communicator (comm.cpp)

  private:
    std::shared_ptr<const Handle> handle_;
    int rank_ = 0, size_ = 1;
};

// An error every rank of a run has thrown at the same point, with the same
// message (Comm::agree): rank 0 reports it and all end together. Any other
// error on several ranks is one rank's alone, and ends them all
// (MpiSession::abort).
class AgreedError : public Error {
  public:
    using Error::Error;
};

// An error every rank finds at the same point, from values that are the
// same on all (a global dt, a global count): no message is needed to agree.
[[noreturn]] inline void fail_together(const Comm &comm, const std::string &message) {
    if (comm.distributed()) throw AgreedError(message);
    throw Error(message);
}

// Runs `f` on every rank and agrees on its outcome (Comm::agree). `f` must
// make no collective call unless it agrees on its own failures first.
template <class F>
void together(const Comm &comm, F &&f) {
    std::exception_ptr error;
    try {
        f();
    } catch (const AgreedError &) {
        throw; // every rank has it already
    } catch (...) {
        error = std::current_exception();
    }
    comm.agree(error);
}

// MPI for the lifetime of a command that runs a simulation on several
// ranks: initialised by the first instance (threads: the OpenMP loops run
// between MPI calls, from the main thread), finalised when it goes. A
// build without MPI, or a process started without a launcher, still works
// (Open MPI initialises a singleton).
class MpiSession {
  public:
    MpiSession(int *argc, char ***argv);
    ~MpiSession();
    MpiSession(const MpiSession &) = delete;
    MpiSession &operator=(const MpiSession &) = delete;
    // Whether a launcher (mpirun, srun) started this process: the ranks it
    // started, from its environment; 1 otherwise.
    static int launched_ranks();
    // Ends every rank at once after an error on one (MPI_Abort): a rank that
    // has failed alone cannot leave the others waiting in a collective.
    [[noreturn]] static void abort(int code);

  private:
    [[maybe_unused]] bool owner_ = false; // this instance initialised MPI (MPI builds only)
};

} // namespace talus
