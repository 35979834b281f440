// The nodes a rank shares with its neighbours, and their sums after a P2G
// (docs/mpi.md, "Exchange"). Each rank scatters its own particles into
// every node it holds, ghost layers included; the shared nodes are then
// exchanged and every rank adds all contributions to a node in ascending
// rank order, so that every rank holding the node has the same bits. The
// grid update, node by node, then gives the same velocities on every copy
// and G2P needs no second exchange.
#pragma once

#include "ranks/decomposition.hpp"
#include "state/grid.hpp"

#include <talus/mpm/comm.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace talus {

class Halo {
  public:
    Halo() = default;
    // Rank `rank`'s shared nodes in `geo`'s local box.
    Halo(const Decomposition &decomp, int rank, const GridGeometry &geo, int ghost);

    // Fields of a node record to sum (bit f: field f of node::); the fixity
    // field's bits are or-ed, not added.
    static constexpr unsigned kMomentumFields = 0b10001111u; // mass, momentum, fixity
    static constexpr unsigned kForceFields = 0b01110000u;
    static constexpr unsigned kRemapFields = 0b00001110u; // momentum alone
    static constexpr unsigned kAllFields = 0xffu;

    // Sums the shared nodes' fields in `records` over the ranks
    // (collective among the neighbours). Returns the bytes this rank sent.
    std::size_t sum(const Comm &comm, double *records, unsigned fields);

    const std::vector<int> &neighbours() const { return peers_; }
    // Nodes held by more than this rank.
    std::size_t shared_nodes() const { return shared_.size(); }
    // The local slots whose values go to (and come from) neighbours()[k],
    // in message order.
    std::vector<std::uint32_t> slots(std::size_t k) const {
        std::vector<std::uint32_t> out;
        for (std::uint32_t pos : positions_[k])
            out.push_back(shared_[pos]);
        return out;
    }

  private:
    int rank_ = 0;
    std::vector<int> peers_; // ascending
    std::vector<std::vector<std::uint32_t>>
        positions_;                     // per peer: into shared_, in the peers' common order
    std::vector<std::uint32_t> shared_; // local slots, ascending
    std::vector<std::vector<std::byte>> send_;
    std::vector<double> own_;
};

} // namespace talus
