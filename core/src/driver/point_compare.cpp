// The `compare:` block of a driver case: the output against a reference CSV,
// column by column, with a tolerance each, so that a driver case can be a
// ctest (a mismatch makes `talus point` exit non-zero).
#include <talus/driver/point_driver.hpp>
#include <talus/error.hpp>
#include <talus/input/csv_table.hpp>

#include <fmt/format.h>

#include <cmath>

namespace talus {

std::string compare_point_rows(const PointCase &pc, const std::vector<PointRow> &all_rows) {
    const CompareSpec &cs = *pc.compare;
    const CsvTable ref = read_csv_table(cs.file, cs.where + ": compare");
    const int rx = ref.column(cs.ref_x);
    if (rx < 0)
        throw Error(fmt::format("{}: error: compare: the reference file {} has no column '{}'",
                                cs.where, cs.file, cs.ref_x));
    const MaterialInstance &model = *pc.instance;
    std::vector<PointRow> rows;
    for (const PointRow &r : all_rows)
        if (cs.stage.empty() ||
            (r.stage > 0 && pc.stages[static_cast<std::size_t>(r.stage - 1)].name == cs.stage))
            rows.push_back(r);
    std::vector<double> x;
    for (const PointRow &r : rows)
        x.push_back(*point_quantity(r, model, pc.axis, cs.x));
    std::string report;
    int failures = 0;
    for (const CompareSpec::Column &col : cs.columns) {
        const int rc = ref.column(col.theirs);
        if (rc < 0)
            throw Error(fmt::format("{}: error: compare: the reference file {} has no column '{}'",
                                    cs.where, cs.file, col.theirs));
        double worst = 0.0;
        std::string worst_text;
        for (const auto &rr : ref.rows) {
            const double xr = rr[static_cast<std::size_t>(rx)];
            const double want = rr[static_cast<std::size_t>(rc)];
            // The first pair of consecutive output rows that brackets x.
            std::optional<double> got;
            for (std::size_t i = 0; i + 1 < rows.size() && !got; ++i) {
                const double a = x[i], b = x[i + 1];
                if ((xr - a) * (xr - b) > 0.0) continue;
                const double w = b != a ? (xr - a) / (b - a) : 0.0;
                const double ya = *point_quantity(rows[i], model, pc.axis, col.ours);
                const double yb = *point_quantity(rows[i + 1], model, pc.axis, col.ours);
                got = ya + w * (yb - ya);
            }
            // A reference x at the very end of the computed range (the
            // driver meets strain conditions to ~1e-12) takes the nearest row.
            double span = 0.0;
            for (double xi : x)
                span = std::max(span, std::abs(xi));
            for (std::size_t i = 0; i < rows.size() && !got; ++i)
                if (std::abs(x[i] - xr) <= 1e-9 * span)
                    got = *point_quantity(rows[i], model, pc.axis, col.ours);
            if (!got) {
                report += fmt::format("  {}: reference {} = {:.9g} lies outside the computed "
                                      "range of {}\n",
                                      col.ours, cs.ref_x, xr, cs.x);
                ++failures;
                continue;
            }
            const double err = std::abs(*got - want);
            const double allowed = col.abs + col.rel * std::abs(want);
            if (err > allowed) {
                ++failures;
                const double ratio = err / allowed;
                if (ratio > worst) {
                    worst = ratio;
                    worst_text = fmt::format("at {} = {:.9g}: {:.12g}, reference {:.12g}, "
                                             "difference {:.3g} > allowed {:.3g}",
                                             cs.x, xr, *got, want, err, allowed);
                }
            }
        }
        if (worst > 0.0)
            report += fmt::format("  {} (reference column {}): worst {}\n", col.ours, col.theirs,
                                  worst_text);
    }
    if (failures == 0) return "";
    return fmt::format("compare: {} value(s) outside tolerance against {}:\n{}", failures, cs.file,
                       report);
}

} // namespace talus
