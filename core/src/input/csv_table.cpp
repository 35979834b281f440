#include <talus/input/csv_table.hpp>
#include <talus/regular_file.hpp>

#include <talus/error.hpp>

#include <fmt/format.h>

#include <fstream>
#include <sstream>

namespace talus {

int CsvTable::column(const std::string &name) const {
    for (std::size_t i = 0; i < header.size(); ++i)
        if (header[i] == name) return static_cast<int>(i);
    return -1;
}

CsvTable read_csv_table(const std::string &file, const std::string &where) {
    if (const std::string why = not_a_regular_file(file); !why.empty())
        throw Error(fmt::format("{}: error: the CSV file '{}': {}", where, file, why));
    std::ifstream in(file);
    if (!in) throw Error(fmt::format("{}: error: cannot open the CSV file '{}'", where, file));
    CsvTable t;
    t.file = file;
    std::string line;
    long number = 0;
    auto trim = [](std::string s) {
        s.erase(0, s.find_first_not_of(" \t"));
        s.erase(s.find_last_not_of(" \t") + 1);
        return s;
    };
    while (std::getline(in, line)) {
        ++number;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.empty() || line[0] == '#') continue;
        std::stringstream ss(line);
        std::string cell;
        std::vector<std::string> cells;
        while (std::getline(ss, cell, ','))
            cells.push_back(trim(cell));
        if (t.header.empty()) {
            t.header = cells;
            continue;
        }
        std::vector<double> row;
        for (const std::string &c : cells) {
            try {
                std::size_t used = 0;
                row.push_back(std::stod(c, &used));
                if (used != c.size()) throw std::invalid_argument(c);
            } catch (const std::exception &) {
                throw Error(fmt::format("{}:{}: error: '{}' is not a number", file, number, c));
            }
        }
        if (row.size() != t.header.size())
            throw Error(fmt::format("{}:{}: error: {} values for {} columns", file, number,
                                    row.size(), t.header.size()));
        t.rows.push_back(std::move(row));
    }
    if (t.rows.empty()) throw Error(fmt::format("{}: error: no data rows in {}", where, file));
    return t;
}

} // namespace talus
