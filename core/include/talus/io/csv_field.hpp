// A text field of a CSV file as RFC 4180 writes it: as it is, unless it
// holds a comma, a double quote or a line break, then in double quotes
// with each double quote doubled. Probe and stage names are the user's and
// may hold any of them; written raw, one would shift every later column.
#pragma once

#include <string>
#include <string_view>

namespace talus {

inline std::string csv_field(std::string_view text) {
    if (text.find_first_of(",\"\r\n") == std::string_view::npos) return std::string(text);
    std::string q = "\"";
    for (const char c : text) {
        if (c == '"') q += '"';
        q += c;
    }
    return q + '"';
}

} // namespace talus
