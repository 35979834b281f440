// A numeric CSV with one header line (lines starting with '#' are comments):
// the reference files of `compare:` and the laboratory files that drive
// `talus point` stages.
#pragma once

#include <string>
#include <vector>

namespace talus {

struct CsvTable {
    std::string file;
    std::vector<std::string> header;
    std::vector<std::vector<double>> rows;
    // Index of the named column, or -1.
    int column(const std::string &name) const;
};

// Reads `file`; errors (missing file, a cell that is not a number, a row of
// the wrong length, no data) name the file and line, after `where`.
CsvTable read_csv_table(const std::string &file, const std::string &where);

} // namespace talus
