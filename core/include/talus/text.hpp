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

// The user's text as a message shows it: whole up to 80 characters, else
// its first 60 and how long it was (a 100 MB value is not echoed whole).
std::string clip(std::string_view text);

// Whether `s` is lower_snake_case: a letter a-z, then a-z, 0-9 or '_' (the
// ABI's identifiers: parameter keys, state names, model ids).
bool is_snake_identifier(std::string_view s);

} // namespace talus
