#include "matplotlib.hpp"

#include <talus/error.hpp>

#include <fmt/format.h>

#include <cstdio>
#include <cstdlib>
#include <sys/wait.h>

namespace talus {

namespace {

std::string quote(const std::string &s) {
    std::string out = "'";
    for (char c : s) {
        if (c == '\'')
            out.append("'\\''");
        else
            out.push_back(c);
    }
    out.push_back('\'');
    return out;
}

} // namespace

void draw_with_matplotlib(const std::string &script, const std::vector<std::string> &args,
                          const std::filesystem::path &png, const std::string &option) {
    // Debian's python3-matplotlib serves /usr/bin/python3; an activated
    // virtual environment earlier in PATH may lack it. TALUS_PYTHON
    // overrides both.
    std::string python = "python3";
    if (const char *env = std::getenv("TALUS_PYTHON"); env && *env)
        python = env;
    else if (std::filesystem::exists("/usr/bin/python3"))
        python = "/usr/bin/python3";
    std::string cmd = fmt::format("{} -", quote(python));
    for (const std::string &a : args)
        cmd += fmt::format(" {}", quote(a));
    cmd += " 2>&1";
    // A stale picture must not pass for the new one.
    std::error_code ec;
    std::filesystem::remove(png, ec);
    FILE *pipe = popen(cmd.c_str(), "w");
    if (!pipe) throw Error(option + ": cannot start python3");
    const bool written = std::fwrite(script.data(), 1, script.size(), pipe) == script.size();
    const int status = pclose(pipe);
    if (!written || status == -1 || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
        throw Error(
            fmt::format("{}: python3 failed to draw {} (exit status {}; its message, if any, "
                        "is above); it needs Debian's python3-matplotlib (or set TALUS_PYTHON "
                        "to a python3 that has matplotlib)",
                        option, png.string(), WIFEXITED(status) ? WEXITSTATUS(status) : -1));
    if (!std::filesystem::exists(png))
        throw Error(fmt::format("{}: {} was not written", option, png.string()));
}

} // namespace talus
