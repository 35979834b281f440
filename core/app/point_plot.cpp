#include "point_plot.hpp"

#include "matplotlib.hpp"

namespace talus {

namespace {

// Reads the CSV by its header names (sys.argv: csv, png, title). Strains in
// percent, stresses in kPa, compression positive, stage boundaries marked on
// the time panel.
constexpr const char *kScript = R"PY(
import csv, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
path, png, title = sys.argv[1], sys.argv[2], sys.argv[3]
with open(path) as f:
    rows = list(csv.DictReader(f))
if not rows:
    sys.exit("no rows in " + path)
col = lambda k: [float(r[k]) for r in rows]
t, stage = col("time"), col("stage")
ea, ev = [100 * v for v in col("eps_a")], [100 * v for v in col("eps_v")]
qa, p = [v / 1e3 for v in col("q_a")], [v / 1e3 for v in col("p")]
sa, sr = [v / 1e3 for v in col("sig_a")], [v / 1e3 for v in col("sig_r")]
span = lambda v: max(v) - min(v)
# A simple-shear test: the largest shear strain dominates the axial one.
shear = max(("xy", "yz", "xz"), key=lambda c: span(col("eps_" + c)))
gamma = [200 * v for v in col("eps_" + shear)]  # engineering, %
tau = [v / 1e3 for v in col("sig_" + shear)]
simple_shear = span(gamma) > 2 * span(ea)
def flat(ax, v):  # a constant series would show its rounding noise
    if span(v) < 1e-9 * max(1.0, max(abs(x) for x in v)):
        m = v[0]
        ax.set_ylim(m - 1, m + 1)
fig, ax = plt.subplots(2, 2, figsize=(11, 8.5))
if simple_shear:
    ax[0][0].plot(gamma, tau, "-", lw=1.2)
    ax[0][0].set_xlabel(f"shear strain gamma_{shear} (%)")
    ax[0][0].set_ylabel(f"shear stress tau_{shear} (kPa)")
    ax[0][1].plot(gamma, sa, "-", lw=1.2); flat(ax[0][1], sa)
    ax[0][1].set_xlabel(f"shear strain gamma_{shear} (%)")
    ax[0][1].set_ylabel("normal stress sig_a (kPa)")
    ax[1][0].plot(sa, tau, "-", lw=1.2)
    ax[1][0].set_xlabel("normal stress sig_a (kPa)"); ax[1][0].set_ylabel(f"tau_{shear} (kPa)")
else:
    ax[0][0].plot(ea, qa, "-", lw=1.2)
    ax[0][0].set_xlabel("axial strain eps_a (%)")
    ax[0][0].set_ylabel("deviator q = sig_a - sig_r (kPa)")
    ax[0][1].plot(ea, ev, "-", lw=1.2); flat(ax[0][1], ev)
    ax[0][1].set_xlabel("axial strain eps_a (%)"); ax[0][1].set_ylabel("volumetric strain eps_v (%)")
    ax[0][1].invert_yaxis()
    ax[1][0].plot(p, qa, "-", lw=1.2)
    ax[1][0].set_xlabel("mean effective stress p' (kPa)"); ax[1][0].set_ylabel("q (kPa)")
ax[1][1].plot(t, sa, label="sig_a (kPa)")
ax[1][1].plot(t, sr, label="sig_r (kPa)")
if simple_shear:
    ax[1][1].plot(t, tau, label=f"tau_{shear} (kPa)")
ax2 = ax[1][1].twinx()
if simple_shear:
    ax2.plot(t, gamma, "k--", lw=1, label=f"gamma_{shear} (%)")
else:
    ax2.plot(t, ea, "k--", lw=1, label="eps_a (%)")
    ax2.plot(t, ev, "k:", lw=1, label="eps_v (%)")
ax2.set_ylabel("strain (%)")
for i in range(1, len(rows)):
    if stage[i] != stage[i - 1]:
        ax[1][1].axvline(t[i - 1], color="0.8", lw=0.8)
ax[1][1].set_xlabel("time (s)"); ax[1][1].set_ylabel("stress (kPa)")
h1, l1 = ax[1][1].get_legend_handles_labels(); h2, l2 = ax2.get_legend_handles_labels()
ax[1][1].legend(h1 + h2, l1 + l2, fontsize=8, loc="best")
for a in ax.flat:
    a.grid(True, lw=0.3)
    a.ticklabel_format(useOffset=False, axis="both", style="plain")
fig.suptitle(title + "  (compression positive; stage starts marked at lower right)")
fig.tight_layout()
fig.savefig(png, dpi=110)
)PY";

} // namespace

void plot_point_csv(const std::filesystem::path &csv, const std::filesystem::path &png,
                    const std::string &title) {
    draw_with_matplotlib(kScript, {csv.string(), png.string(), title}, png, "--plot");
}

} // namespace talus
