"""Run by pvbatch (ParaView's Python): reads an XDMF file with one of ParaView's XDMF readers and
prints, as JSON, its time steps and, at the time step given, every block: points, cell count and
cell types, and every point and cell array.

    pvbatch xdmf_dump.py RUN.xdmf TIME_INDEX [legacy|xdmf3]

legacy: "XDMF Reader" (the XDMF 2 library; blocks by their grid's name); xdmf3: "Xdmf3ReaderS"
(blocks unnamed: named here by their order, colliders first when there are two).
"""
import json
import os
import sys

from paraview import servermanager, simple
from vtk.util.numpy_support import vtk_to_numpy

path, index = os.path.abspath(sys.argv[1]), int(sys.argv[2])
which = sys.argv[3] if len(sys.argv) > 3 else "legacy"
if which == "legacy":
    reader = simple.XDMFReader(FileNames=[path])
else:
    reader = simple.Xdmf3ReaderS(FileName=[path])
reader.UpdatePipelineInformation()
times = list(reader.TimestepValues)
reader.UpdatePipeline(times[index])
data = servermanager.Fetch(reader)


def blocks_of(data):
    """[(name or None, data set)]: a file of one collection (the body alone) reads as one data set."""
    if not data.IsA("vtkMultiBlockDataSet"):
        return [("body", data)]
    out = []
    it = data.NewIterator()
    it.InitTraversal()
    while not it.IsDoneWithTraversal():
        meta = it.GetCurrentMetaData()
        out.append((meta.Get(data.NAME()) if meta.Has(data.NAME()) else None, it.GetCurrentDataObject()))
        it.GoToNextItem()
    return out


found = []
for name, block in blocks_of(data):
    entry = {
        "points": vtk_to_numpy(block.GetPoints().GetData()).tolist(),
        "cells": block.GetNumberOfCells(),
        "cell_types": [block.GetCellType(k) for k in range(block.GetNumberOfCells())],
        "point_arrays": {},
        "cell_arrays": {},
    }
    for kind, arrays in (("point_arrays", block.GetPointData()), ("cell_arrays", block.GetCellData())):
        for k in range(arrays.GetNumberOfArrays()):
            entry[kind][arrays.GetArrayName(k)] = vtk_to_numpy(arrays.GetArray(k)).tolist()
    found.append((name.split("[")[0] if name else None, entry))
if any(name is None for name, _ in found):
    order = ["colliders", "body"] if len(found) == 2 else ["body"]
    found = [(order[k], entry) for k, (_, entry) in enumerate(found)]
print("JSON" + json.dumps({"times": times, "blocks": dict(found)}, allow_nan=True))
