// Words for messages: the "did you mean" of every misspelt name.
#pragma once

#include <span>
#include <string>
#include <string_view>

namespace talus {

// The candidate closest to `word` by edit distance, or "" if none is close
// enough to be a plausible misspelling.
std::string closest_match(std::string_view word, std::span<const std::string_view> candidates);
std::string closest_match(std::string_view word, std::span<const std::string> candidates);

} // namespace talus
