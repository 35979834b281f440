// The batch arrays of the conformance checks, each with a guard band of
// canary values before and after it: a plugin that writes past the end of
// its state or stress array (a wrong stride, an off-by-one) changes a
// canary, which the check names, where in a run it would corrupt the next
// array in memory and crash later in the host, or pass unseen.
#pragma once

#include <fmt/format.h>

#include <cstdint>
#include <cstring>
#include <mutex>
#include <string>
#include <vector>

namespace talus::check {

class GuardedArray {
  public:
    // 16 values, 128 bytes, each side: past a whole point of stress (6) or
    // tangent (36 would reach beyond; a write that far is caught where it
    // lands in the band) and past a state of up to 16 values.
    static constexpr std::size_t kGuard = 16;

    explicit GuardedArray(std::size_t n, double value = 0.0) : v_(n + 2 * kGuard, value), n_(n) {
        for (std::size_t k = 0; k < kGuard; ++k) {
            v_[k] = canary(k);
            v_[kGuard + n + k] = canary(kGuard + k);
        }
    }
    double *data() { return v_.data() + kGuard; }
    const double *data() const { return v_.data() + kGuard; }
    double &operator[](std::size_t i) { return v_[kGuard + i]; }
    double operator[](std::size_t i) const { return v_[kGuard + i]; }
    std::size_t size() const { return n_; }
    double *begin() { return data(); }
    double *end() { return data() + n_; }

    // "1 value(s) past the end of NAME", "... before the start of NAME", or
    // empty when both bands are intact.
    std::string damage(const char *name) const {
        std::size_t before = 0, after = 0;
        for (std::size_t k = 0; k < kGuard; ++k) {
            before += !same(v_[k], canary(k));
            after += !same(v_[kGuard + n_ + k], canary(kGuard + k));
        }
        std::string s;
        if (after) s = fmt::format("{} value(s) past the end of {}", after, name);
        if (before)
            s += fmt::format("{}{} value(s) before the start of {}", s.empty() ? "" : " and ",
                             before, name);
        return s;
    }

  private:
    // A quiet NaN with a payload no arithmetic makes, different per slot.
    static double canary(std::size_t k) {
        const std::uint64_t bits = 0x7ff8c0ffee000000ull | k;
        double d;
        std::memcpy(&d, &bits, sizeof d);
        return d;
    }
    static bool same(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
    std::vector<double> v_;
    std::size_t n_;
};

// The first write outside a batch's arrays the checks saw (from any
// thread), and how many batches had one.
class Overruns {
  public:
    void note(const std::string &what) {
        const std::lock_guard lock(m_);
        if (count_++ == 0) first_ = what;
    }
    std::string first() const {
        const std::lock_guard lock(m_);
        return first_;
    }
    void clear() {
        const std::lock_guard lock(m_);
        first_.clear();
        count_ = 0;
    }
    std::size_t count() const {
        const std::lock_guard lock(m_);
        return count_;
    }

  private:
    mutable std::mutex m_;
    std::string first_;
    std::size_t count_ = 0;
};

} // namespace talus::check
