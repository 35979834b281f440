// Text the user named, written into an XML file (VTK, its collections):
// what XML reserves escaped.
#pragma once

#include <string>
#include <string_view>

namespace talus {

inline std::string xml_escape(std::string_view s) {
    std::string out;
    for (const char c : s) {
        switch (c) {
        case '&': out += "&amp;"; break;
        case '<': out += "&lt;"; break;
        case '>': out += "&gt;"; break;
        case '"': out += "&quot;"; break;
        default: out += c;
        }
    }
    return out;
}

} // namespace talus
