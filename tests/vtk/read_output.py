"""Reads a `talus run` output folder with VTK's own XML readers (the ones
ParaView uses) and checks what it finds against the run's diagnostics.csv:
the .pvd lists every frame, each .vtu (or .pvtu and its pieces) opens, has one vertex per particle and
the documented fields, and the particles' total mass (rho0 V0 from volume / J)
matches the diagnostics. Exit status 0 when all holds."""
import csv
import math
import sys
import xml.etree.ElementTree as ET

import vtk


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def names(grid, key):
    arr = grid.GetFieldData().GetAbstractArray(key)
    if arr is None:
        fail(f"no field data '{key}'")
    return [arr.GetVariantValue(k).ToString() for k in range(arr.GetNumberOfValues())]


def main(folder, density, groups, materials):
    rows = list(csv.DictReader(open(f"{folder}/diagnostics.csv")))
    frames = ET.parse(f"{folder}/particles.pvd").getroot().findall(".//DataSet")
    if len(frames) != len(rows):
        fail(f"{len(frames)} frames in the .pvd, {len(rows)} rows in diagnostics.csv")
    expected = {"id": 1, "group": 1, "material": 1, "displacement": 3, "velocity": 3, "stress": 9,
                "p": 1, "q": 1, "volume": 1, "J": 1, "density": 1, "mass": 1, "F": 9}
    for frame, row in zip(frames, rows):
        if abs(float(frame.get("timestep")) - float(row["time"])) > 1e-12:
            fail(f"frame time {frame.get('timestep')} != {row['time']}")
        # A run on several ranks writes a .pvtu naming a piece per rank.
        parallel = frame.get("file").endswith(".pvtu")
        reader = vtk.vtkXMLPUnstructuredGridReader() if parallel else vtk.vtkXMLUnstructuredGridReader()
        reader.SetFileName(f"{folder}/{frame.get('file')}")
        reader.Update()
        grid = reader.GetOutput()
        n = int(row["particles"])
        if grid.GetNumberOfPoints() != n or grid.GetNumberOfCells() != n:
            fail(f"{frame.get('file')}: {grid.GetNumberOfPoints()} points, expected {n}")
        pd = grid.GetPointData()
        for name, comps in expected.items():
            arr = pd.GetArray(name)
            if arr is None:
                fail(f"{frame.get('file')}: no array '{name}'")
            if arr.GetNumberOfComponents() != comps:
                fail(f"{name}: {arr.GetNumberOfComponents()} components, expected {comps}")
        # The name tables, in the order of the scenario file.
        if names(grid, "group_names") != groups or names(grid, "material_names") != materials:
            fail(f"name tables {names(grid, 'group_names')}, {names(grid, 'material_names')}; "
                 f"expected {groups}, {materials}")
        if abs(grid.GetFieldData().GetArray("TimeValue").GetValue(0) - float(row["time"])) > 1e-12:
            fail("TimeValue differs from the frame time")
        volume, J, stress = pd.GetArray("volume"), pd.GetArray("J"), pd.GetArray("stress")
        # density * volume is the particle mass, and the density is rho0 / J
        # (mass conservation); det F is J. Tolerances: the file holds the
        # doubles the solver had, so only the round-off of one product or
        # quotient (1e-16 relative) separates the two sides of the first two;
        # det F summed in another order than the solver's differs by about
        # 1e-15 for J near 1, far inside 1e-9.
        rho, m, F = pd.GetArray("density"), pd.GetArray("mass"), pd.GetArray("F")
        for i in range(n):
            if abs(rho.GetValue(i) * volume.GetValue(i) - m.GetValue(i)) > 1e-12 * m.GetValue(i):
                fail("density * volume differs from mass")
            if abs(rho.GetValue(i) * J.GetValue(i) - density) > 1e-9 * density:
                fail("density * J differs from the material density")
            f = F.GetTuple9(i)
            det = (f[0] * (f[4] * f[8] - f[5] * f[7]) - f[1] * (f[3] * f[8] - f[5] * f[6])
                   + f[2] * (f[3] * f[7] - f[4] * f[6]))
            if abs(det - J.GetValue(i)) > 1e-9:
                fail(f"det F = {det}, J = {J.GetValue(i)}")
        mass = sum(density * volume.GetValue(i) / J.GetValue(i) for i in range(n))
        if abs(mass - float(row["mass"])) > 1e-9 * mass:
            fail(f"mass {mass} from the VTK file, {row['mass']} in diagnostics.csv")
        for i in range(n):
            s = stress.GetTuple9(i)
            scale = max(abs(x) for x in s) + 1.0
            if abs(s[1] - s[3]) > 1e-9 * scale or abs(s[2] - s[6]) > 1e-9 * scale or abs(s[5] - s[7]) > 1e-9 * scale:
                fail("stress tensors are not symmetric")
        ids = {int(pd.GetArray("id").GetValue(i)) for i in range(n)}
        if len(ids) != n:
            fail("particle ids are not unique")
        points = grid.GetPoints()
        if not all(math.isfinite(c) for i in range(n) for c in points.GetPoint(i)):
            fail("non-finite point coordinates")
    print(f"read {len(frames)} frames of {rows[-1]['particles']} particles with VTK {vtk.vtkVersion.GetVTKVersion()}")


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), sys.argv[3].split(","), sys.argv[4].split(","))
