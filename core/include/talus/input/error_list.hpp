// The errors of a file's independent parts, each with its place, so that
// one `talus validate` reports them all (up to kShown) instead of the first
// alone. A part is read in attempt(); what depends on a part that failed
// is not read, so that one mistake is not reported again as the errors it
// causes further on (a group of a material that failed is not "of no
// material").
#pragma once

#include <talus/error.hpp>

#include <cstddef>
#include <string>
#include <vector>

namespace talus::yaml {

class ErrorList {
  public:
    static constexpr std::size_t kShown = 20;

    // Runs `read`; a talus::Error it throws is kept. Returns whether it
    // read without one.
    template <class Read>
    bool attempt(Read &&read) {
        try {
            read();
            return true;
        } catch (const Error &e) {
            messages_.emplace_back(e.what());
            return false;
        }
    }
    bool empty() const { return messages_.empty(); }

    // Throws one Error holding every message (the first kShown, then how
    // many more), if there are any.
    void throw_if_any() const {
        if (messages_.empty()) return;
        if (messages_.size() == 1) throw Error(messages_[0]);
        std::string all;
        for (std::size_t k = 0; k < messages_.size() && k < kShown; ++k)
            all += (k ? "\n" : "") + messages_[k];
        if (messages_.size() > kShown)
            all += "\n... and " + std::to_string(messages_.size() - kShown) +
                   " more error(s), not shown";
        all += "\n" + std::to_string(messages_.size()) + " errors";
        throw Error(all);
    }

  private:
    std::vector<std::string> messages_;
};

} // namespace talus::yaml
