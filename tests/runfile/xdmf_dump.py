"""Run by pvbatch (ParaView's Python): reads an XDMF file with ParaView's own XDMF reader and
prints, as JSON, its time steps and, at the time step given, every block: points, cell count
and cell connectivity sizes, and every point and cell array.

    pvbatch xdmf_dump.py RUN.xdmf TIME_INDEX
"""
import json
import sys

from paraview import servermanager, simple
from vtk.util.numpy_support import vtk_to_numpy

reader = simple.XDMFReader(FileNames=[sys.argv[1]])
reader.UpdatePipelineInformation()
times = list(reader.TimestepValues)
index = int(sys.argv[2])
reader.UpdatePipeline(times[index])
data = servermanager.Fetch(reader)
blocks = {}
it = data.NewIterator()
it.InitTraversal()
while not it.IsDoneWithTraversal():
    block = it.GetCurrentDataObject()
    name = it.GetCurrentMetaData().Get(data.NAME()).split("[")[0]
    entry = {
        "points": vtk_to_numpy(block.GetPoints().GetData()).tolist(),
        "cells": block.GetNumberOfCells(),
        "cell_types": sorted({block.GetCellType(k) for k in range(block.GetNumberOfCells())}),
        "point_arrays": {},
        "cell_arrays": {},
    }
    for kind, arrays in (("point_arrays", block.GetPointData()), ("cell_arrays", block.GetCellData())):
        for k in range(arrays.GetNumberOfArrays()):
            entry[kind][arrays.GetArrayName(k)] = vtk_to_numpy(arrays.GetArray(k)).tolist()
    blocks[name] = entry
    it.GoToNextItem()
print("JSON" + json.dumps({"times": times, "blocks": blocks}, allow_nan=True))
