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

// Whether `s` is lower_snake_case: a letter a-z, then a-z, 0-9 or '_' (the
// ABI's identifiers: parameter keys, state names, model ids).
bool is_snake_identifier(std::string_view s);

} // namespace talus
