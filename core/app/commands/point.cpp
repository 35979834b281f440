// talus point: a material-point driver case (docs/point-driver.md), its CSV
// and provenance, optionally its plot and its comparison with a reference.
#include "commands.hpp"

#include "../point_plot.hpp"

#include <talus/driver/point_driver.hpp>
#include <talus/error.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/io/output_file.hpp>
#include <talus/io/provenance.hpp>

#include <fmt/format.h>

#include <filesystem>
#include <iostream>
#include <sstream>

namespace talus::cli {

namespace {

class Point final : public Command {
  public:
    explicit Point(CLI::App &parent)
        : Command(parent.add_subcommand("point",
                                        "Run a single material-point test (driver case YAML)")) {
        app_->add_option("case", case_file_, "Driver case file (YAML)")
            ->required()
            ->type_name("CASE.yaml");
        app_->add_option("-o,--output", csv_out_, "Write the CSV here instead of standard output")
            ->type_name("OUT.csv");
        app_->add_option("--plot", plot_png_,
                         "Also draw the four panels of a soil test (q and volumetric strain "
                         "against axial strain, the q - p' path, the controlled quantities) with "
                         "matplotlib")
            ->type_name("FILE.png");
        app_->add_flag("--print-stages", show_stages_,
                       "Print each stage's six conditions (presets expanded) and stop");
    }
    bool calls_plugins() const override { return true; }
    int run(Context &ctx) override;

  private:
    // The rows, written where the user asked; a failed case's rows beside it.
    std::string run_rows(const PointCase &pc, std::vector<PointRow> &rows) const;
    void plot(const PointCase &pc, const std::string &csv) const;

    std::string case_file_, csv_out_, plot_png_;
    bool show_stages_ = false;
};

// What made the rows: beside the CSV file, or on stderr when the CSV goes
// to stdout (which stays plain CSV).
void write_provenance(const Provenance &prov, const std::string &csv_file) {
    if (csv_file.empty())
        std::cerr << provenance_comments(prov);
    else
        write_file_atomically(csv_file + ".provenance.json", provenance_json(prov));
}

std::string Point::run_rows(const PointCase &pc, std::vector<PointRow> &rows) const {
    Provenance prov;
    prov.command = "point";
    prov.input_file = case_file_;
    prov.materials = {{"material", &pc.material}};
    auto csv_text = [&] {
        std::ostringstream csv;
        write_point_csv(csv, *pc.instance, pc.axis, rows);
        return csv.str();
    };
    try {
        run_point_case(pc, rows);
    } catch (const Error &e) {
        // The rows up to the failure go beside the requested file, under a
        // name that cannot be mistaken for a result.
        if (csv_out_.empty() || rows.empty()) throw;
        const std::string partial = csv_out_ + ".failed.csv";
        write_file_atomically(partial, csv_text());
        write_provenance(prov, partial);
        throw Error(fmt::format("{}\n(the {} rows computed until then are in {}; {} was not "
                                "written)",
                                e.what(), rows.size(), partial, csv_out_));
    }
    const std::string csv = csv_text();
    if (csv_out_.empty())
        std::cout << csv;
    else
        write_file_atomically(csv_out_, csv);
    write_provenance(prov, csv_out_);
    return csv;
}

void Point::plot(const PointCase &pc, const std::string &csv) const {
    std::filesystem::path source = csv_out_;
    std::filesystem::path tmp;
    if (csv_out_.empty()) {
        tmp = std::filesystem::path(plot_png_).replace_extension(".plot-data.csv");
        write_file_atomically(tmp, csv);
        source = tmp;
    }
    plot_point_csv(source, plot_png_,
                   fmt::format("{} - {}", std::filesystem::path(case_file_).filename().string(),
                               pc.instance->model().id()));
    if (!tmp.empty()) std::filesystem::remove(tmp);
}

int Point::run(Context &ctx) {
    refuse_wrong_file(case_file_, YamlKind::point_case, "point");
    const yaml::Node root = yaml::load_file(case_file_);
    const PointCase pc = read_point_case(root, ctx.registry);
    if (show_stages_) {
        print_stages(std::cout, pc);
        return 0;
    }
    std::vector<PointRow> rows;
    const std::string csv = run_rows(pc, rows);
    if (!plot_png_.empty()) plot(pc, csv);
    if (pc.compare) {
        const std::string report = compare_point_rows(pc, rows);
        if (!report.empty()) {
            std::cerr << "talus point: " << report;
            return 3;
        }
        if (ctx.verbosity != Verbosity::quiet)
            std::cerr << fmt::format("talus point: compare: every value within tolerance of {}\n",
                                     pc.compare->file);
    }
    return 0;
}

} // namespace

std::unique_ptr<Command> point_command(CLI::App &parent) { return std::make_unique<Point>(parent); }

} // namespace talus::cli
