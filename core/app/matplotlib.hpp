// Drawing with Debian's python3-matplotlib: the CLI's --plot options hand a
// script and its arguments to python3 rather than link a plotting library.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace talus {

// Runs `script` (Python source, fed on standard input) with `args` as
// sys.argv[1:], and checks that it wrote `png`. The interpreter is
// $TALUS_PYTHON, else /usr/bin/python3 (where Debian's matplotlib lives),
// else python3 from PATH. Throws talus::Error naming `option` when python3
// or matplotlib is missing or the script fails.
void draw_with_matplotlib(const std::string &script, const std::vector<std::string> &args,
                          const std::filesystem::path &png, const std::string &option);

} // namespace talus
