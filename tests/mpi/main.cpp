// The MPI tests' main: GoogleTest on every rank, its report from rank 0,
// and a failure on any rank fails every rank's exit status.
#include <talus/mpm/comm.hpp>

#include <gtest/gtest.h>

int main(int argc, char **argv) {
    talus::MpiSession mpi(&argc, &argv);
    testing::InitGoogleTest(&argc, argv);
    const talus::Comm comm = talus::Comm::world();
    if (comm.rank() != 0) {
        auto &listeners = testing::UnitTest::GetInstance()->listeners();
        delete listeners.Release(listeners.default_result_printer());
    }
    const int failed = RUN_ALL_TESTS() != 0 ? 1 : 0;
    return comm.sum(static_cast<long>(failed)) > 0 ? 1 : 0;
}
