"""Checks that the last VTK frame of a run carries a plugin state variable:
finite (and at least 1, the plugin counts its calls) on the particles of the
group whose material has it, NaN on the others."""
import math
import sys
import xml.etree.ElementTree as ET

import vtk

folder, name, group = sys.argv[1], sys.argv[2], int(sys.argv[3])
frames = ET.parse(f"{folder}/particles.pvd").getroot().findall(".//DataSet")
reader = vtk.vtkXMLUnstructuredGridReader()
reader.SetFileName(f"{folder}/{frames[-1].get('file')}")
reader.Update()
pd = reader.GetOutput().GetPointData()
arr, grp = pd.GetArray(name), pd.GetArray("group")
if arr is None:
    print(f"FAIL: no array '{name}'")
    sys.exit(1)
for i in range(arr.GetNumberOfTuples()):
    v, g = arr.GetValue(i), int(grp.GetValue(i))
    if g == group and not (math.isfinite(v) and v >= 1.0):
        print(f"FAIL: particle {i} of group {g}: {name} = {v}")
        sys.exit(1)
    if g != group and not math.isnan(v):
        print(f"FAIL: particle {i} of group {g} has {name} = {v}, expected NaN")
        sys.exit(1)
print(f"{name}: present, finite on group {group}, NaN elsewhere")
