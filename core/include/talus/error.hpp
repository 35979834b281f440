// Errors the core reports to users. Every message is complete on its own:
// where (file:line:column when known), what, and what was expected.
#pragma once

#include <stdexcept>
#include <string>

namespace talus {

// Bad input, a failed plugin, a refused operation: anything a user can fix.
class Error : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

} // namespace talus
