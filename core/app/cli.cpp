#include "cli.hpp"

#include <talus/regular_file.hpp>

#include <talus/error.hpp>
#include <talus/mpm/simulation.hpp>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <stdexcept>

namespace talus::cli {

const CLI::Validator kPositive(
    [](std::string &text) -> std::string {
        std::size_t used = 0;
        double v = 0.0;
        try {
            v = std::stod(text, &used);
        } catch (const std::out_of_range &) {
            return "out of range, got " + text;
        } catch (const std::exception &) {
            used = 0;
        }
        if (used == 0 || used != text.size()) return "expected a number, got '" + text + "'";
        return v > 0.0 ? std::string() : "must be greater than 0, got " + text;
    },
    "POSITIVE");

const CLI::Validator kThreadCount(
    [](std::string &text) -> std::string {
        std::size_t used = 0;
        long long n = 0;
        try {
            n = std::stoll(text, &used);
        } catch (const std::out_of_range &) {
            // Beyond a long long: far too many, or with a minus far too few.
            used = text.size();
            n = text.find('-') == std::string::npos ? kMaxThreads + 1LL : 0;
        } catch (const std::exception &) {
            used = 0;
        }
        if (used == 0 || used != text.size())
            return "expected a whole number of threads, got '" + text + "'";
        if (n <= 0) return "must be greater than 0, got " + text;
        if (n > kMaxThreads)
            return fmt::format("at most {} threads, got {} (this machine lets talus run on {} "
                               "processor(s))",
                               kMaxThreads, text, Simulation::processors());
        return std::string();
    },
    "COUNT");

YamlKind yaml_kind(const std::string &file) {
    try {
        // Read as every input is (a FIFO is refused, not waited on).
        const YAML::Node n = YAML::Load(read_regular_file(file));
        if (!n.IsMap()) return YamlKind::other;
        if (n["groups"] || n["grid"]) return YamlKind::scenario;
        if (n["strain"] || (n["material"] && !n["materials"])) return YamlKind::point_case;
    } catch (const std::exception &) {
    }
    return YamlKind::other;
}

bool is_yaml_name(const std::string &s) {
    auto ends = [&](const char *e) {
        const std::string x = e;
        return s.size() > x.size() && s.compare(s.size() - x.size(), x.size(), x) == 0;
    };
    return ends(".yaml") || ends(".yml");
}

void refuse_wrong_file(const std::string &file, YamlKind want, const char *command) {
    const YamlKind k = yaml_kind(file);
    if (k == YamlKind::other || k == want) return;
    throw Error(k == YamlKind::scenario
                    ? fmt::format("{}: this is a scenario (it has groups: and grid:), not what "
                                  "`talus {}` reads; run it with `talus run {}` or check it with "
                                  "`talus validate {}`",
                                  file, command, file, file)
                    : fmt::format("{}: this is a material-point driver case (it has material:, "
                                  "not materials: and groups:), not what `talus {}` reads; run "
                                  "it with `talus point {}`",
                                  file, command, file));
}

} // namespace talus::cli
