#include "particle_plot.hpp"

#include "matplotlib.hpp"

namespace talus {

namespace {

// sys.argv: csv, png, title. The marker area follows the particles'
// spacing (the extent per particle), so a dense body reads as solid and a
// spread-out one shows its gaps.
constexpr const char *kScript = R"PY(
import csv, math, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
src, png, title = sys.argv[1], sys.argv[2], sys.argv[3]
with open(src, newline="") as f:
    r = csv.reader(f)
    head = next(r)
    rows = [[float(v) for v in row] for row in r]
if not rows:
    sys.exit("no particles to draw")
field = head[-1]
three = "z" in head
ix, iy = head.index("x"), head.index("z" if three else "y")
x = [row[ix] for row in rows]
y = [row[iy] for row in rows]
c = [row[-1] for row in rows]
w = max(x) - min(x)
h = max(y) - min(y)
# The figure follows the body's shape; the colour scale stops at the 98th
# percentile so that a few extreme particles (a flow front) do not wash out
# the rest (the colour bar then shows an arrow).
fig, ax = plt.subplots(figsize=(10, min(max(10 * h / max(w, 1e-300) + 1.8, 3.0), 9.0)))
finite = sorted(v for v in c if math.isfinite(v))
lo = finite[0] if finite else 0.0
hi = finite[min(len(finite) - 1, int(0.98 * len(finite)))] if finite else 1.0
clipped = bool(finite) and finite[-1] > hi
if hi <= lo:
    hi = lo + 1.0
ax.set_aspect("equal")
ax.set_xlim(min(x) - 0.05 * max(w, h), max(x) + 0.05 * max(w, h))
ax.set_ylim(min(y) - 0.05 * max(w, h), max(y) + 0.1 * max(w, h))
fig.canvas.draw()
# Points per data unit, then a marker a little wider than one particle's
# share of the body (its area over the count, in the plane drawn).
bb = ax.get_window_extent()
ppu = bb.width * 72.0 / fig.dpi / (ax.get_xlim()[1] - ax.get_xlim()[0])
spacing = math.sqrt(max(w * h, 1e-300) / len(x)) if not three else max(w, h) / math.sqrt(len(x))
size = max((1.3 * spacing * ppu) ** 2, 0.5)
sc = ax.scatter(x, y, c=c, s=size, marker="s", linewidths=0, cmap="viridis", vmin=lo, vmax=hi)
cb = fig.colorbar(sc, ax=ax, shrink=0.8, extend="max" if clipped else "neither")
cb.set_label(field + (f" (max {finite[-1]:.3g})" if clipped else ""))
ax.set_xlabel("x (m)")
ax.set_ylabel(("z" if three else "y") + " (m)")
ax.set_title(title)
ax.grid(True, lw=0.3)
fig.tight_layout()
fig.savefig(png, dpi=110)
)PY";

} // namespace

void plot_final_particles(const std::filesystem::path &csv, const std::filesystem::path &png,
                          const std::string &title) {
    draw_with_matplotlib(kScript, {csv.string(), png.string(), title}, png, "--plot");
}

} // namespace talus
