#include <talus/text.hpp>

#include <algorithm>
#include <vector>

namespace talus {

namespace {

// Optimal-string-alignment distance (Levenshtein plus adjacent swaps), the
// usual measure for typing mistakes.
std::size_t edit_distance(std::string_view a, std::string_view b) {
    const std::size_t n = a.size(), m = b.size();
    std::vector<std::size_t> prev2(m + 1), prev(m + 1), cur(m + 1);
    for (std::size_t j = 0; j <= m; ++j)
        prev[j] = j;
    for (std::size_t i = 1; i <= n; ++i) {
        cur[0] = i;
        for (std::size_t j = 1; j <= m; ++j) {
            const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
            cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + cost});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
                cur[j] = std::min(cur[j], prev2[j - 2] + 1);
        }
        prev2.swap(prev);
        prev.swap(cur);
    }
    return prev[m];
}

template <class S>
std::string closest_impl(std::string_view word, std::span<const S> candidates) {
    // A word of hundreds of characters is no misspelt name (and its edit
    // distance to each candidate would cost its length times theirs).
    if (word.size() > 200) return {};
    std::string best;
    std::size_t best_d = std::string_view::npos;
    for (const auto &c : candidates) {
        const std::size_t d = edit_distance(word, c);
        if (d < best_d) {
            best_d = d;
            best = std::string(c);
        }
    }
    // Two edits, or a third of the word for long keys, still reads as the
    // same word; beyond that a suggestion is more confusing than helpful.
    const std::size_t limit = std::max<std::size_t>(2, word.size() / 3);
    return best_d <= limit ? best : std::string();
}

} // namespace

std::string closest_match(std::string_view word, std::span<const std::string_view> candidates) {
    return closest_impl(word, candidates);
}
std::string closest_match(std::string_view word, std::span<const std::string> candidates) {
    return closest_impl(word, candidates);
}

std::string clip(std::string_view text) {
    if (text.size() <= 80) return std::string(text);
    return std::string(text.substr(0, 60)) + "... (" + std::to_string(text.size()) + " characters)";
}

bool is_snake_identifier(std::string_view s) {
    if (s.empty() || !(s[0] >= 'a' && s[0] <= 'z')) return false;
    return std::all_of(s.begin(), s.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
    });
}

} // namespace talus
