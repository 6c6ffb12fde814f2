"""Opens the output of io.test_frame_writer the way ParaView does (VTK's vtkXdmfReader) and
checks time steps, point and cell counts, array names and the values of every body.

Usage: check_xdmf.py OUTPUT_DIR. Exits non-zero with a message per failed check.
The body set-up repeats make_bodies/move_to in test_frame_writer.f90."""
import math
import sys

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline
from vtkmodules.vtkIOXdmf2 import vtkXdmfReader

# Values are written as f64 and computed here from the same inputs with one or two
# roundings more (rotation of the box corners): 1e-12 m is far below any layout error
# (a wrong row or column is off by 0.1 m or more).
TOL = 1e-12
TIMES = [0.0, 0.1, 0.2]
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL: " + what)


def reader_at(path, time):
    reader = vtkXdmfReader()
    reader.SetFileName(path)
    reader.UpdateInformation()
    steps = reader.GetOutputInformation(0).Get(vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    reader.UpdateTimeStep(time)
    data = reader.GetOutputDataObject(0)
    return (list(steps) if steps else []), data


def arrays(field):
    return {field.GetArrayName(i): vtk_to_numpy(field.GetArray(i)) for i in range(field.GetNumberOfArrays())}


def rot_x90(p):
    """R(q) of quat_exp([pi/2, 0, 0]): (x, y, z) -> (x, -z, y)."""
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)


def body_state(t):
    x = {1: np.array([0.0, 0.0, 3.0]) + t * np.array([0.0, 0.0, -1.0]),
         2: np.array([2.0, 0.0, 0.0]) + t * np.array([1.0, 0.0, 0.0]),
         3: np.array([-2.0, 0.0, 0.0]) + t * np.array([0.0, 2.0, 0.0])}
    v = {1: np.array([0.0, 0.0, -1.0]), 2: np.array([1.0, 0.0, 0.0]), 3: np.array([0.0, 2.0, 0.0])}
    w = {1: np.zeros(3), 2: np.array([0.0, 0.0, 1.0]), 3: np.array([0.5, 0.0, 0.0])}
    return x, v, w


BOX = np.array([[sx * 0.5, sy * 1.0, sz * 1.5] for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)])


def sorted_rows(a):
    return a[np.lexsort(np.round(a, 9).T[::-1])]


def check_surfaces(path):
    for t in TIMES:
        steps, grid = reader_at(path, t)
        check(np.allclose(steps, TIMES, rtol=0, atol=0), f"surfaces: time steps {steps} != {TIMES}")
        check(grid.GetNumberOfPoints() == 162 + 8 + 8, f"surfaces t={t}: {grid.GetNumberOfPoints()} points, expected 178")
        check(grid.GetNumberOfCells() == 320 + 12 + 12, f"surfaces t={t}: {grid.GetNumberOfCells()} cells, expected 344")
        cells = arrays(grid.GetCellData())
        point_arrays = arrays(grid.GetPointData())
        check("body_id" in cells, f"surfaces: cell arrays {sorted(cells)} lack body_id")
        check("velocity" in point_arrays, f"surfaces: point arrays {sorted(point_arrays)} lack velocity")
        if "body_id" not in cells or "velocity" not in point_arrays:
            return
        points = vtk_to_numpy(grid.GetPoints().GetData())
        velocity = point_arrays["velocity"]
        check(velocity.shape == (178, 3), f"surfaces: velocity shape {velocity.shape}")
        body_id = cells["body_id"]
        x, v, w = body_state(t)
        for gid, n_cells in ((1, 320), (2, 12), (3, 12)):
            cell_ids = np.nonzero(body_id == gid)[0]
            check(len(cell_ids) == n_cells, f"surfaces t={t}: body {gid} has {len(cell_ids)} cells, expected {n_cells}")
            ids = sorted({grid.GetCell(int(c)).GetPointId(k) for c in cell_ids for k in range(3)})
            check(all(grid.GetCellType(int(c)) == 5 for c in cell_ids), f"surfaces: body {gid} cells are not triangles")
            p = points[ids]
            arm = p - x[gid]
            if gid == 1:
                check(np.allclose(np.linalg.norm(arm, axis=1), 0.5, rtol=0, atol=TOL),
                      f"surfaces t={t}: sphere points not at radius 0.5 from its centre")
            else:
                expected = BOX if gid == 2 else rot_x90(BOX)
                check(len(ids) == 8 and np.allclose(sorted_rows(arm), sorted_rows(expected), rtol=0, atol=TOL),
                      f"surfaces t={t}: box {gid} corners misplaced")
            expected_v = v[gid] + np.cross(w[gid], arm)
            check(np.allclose(velocity[ids], expected_v, rtol=0, atol=TOL),
                  f"surfaces t={t}: point velocities of body {gid} are not v + w x r")


def check_bodies(path):
    half = math.sqrt(0.5)
    orientation = {1: [1.0, 0.0, 0.0, 0.0], 2: [half, 0.0, 0.0, -half], 3: [0.5, 0.5, 0.5, -0.5]}
    for t in TIMES:
        steps, grid = reader_at(path, t)
        check(np.allclose(steps, TIMES, rtol=0, atol=0), f"bodies: time steps {steps} != {TIMES}")
        check(grid.GetNumberOfPoints() == 3, f"bodies t={t}: {grid.GetNumberOfPoints()} points, expected 3")
        check(grid.GetNumberOfCells() == 3, f"bodies t={t}: {grid.GetNumberOfCells()} cells, expected 3 (Polyvertex)")
        a = arrays(grid.GetPointData())
        names = {"gid", "shape_id", "group_id", "velocity", "angular_velocity", "orientation"}
        check(names <= set(a), f"bodies: point arrays {sorted(a)} lack {sorted(names - set(a))}")
        if not names <= set(a):
            return
        check(a["orientation"].shape == (3, 4), f"bodies: orientation shape {a['orientation'].shape}, expected (3, 4)")
        points = vtk_to_numpy(grid.GetPoints().GetData())
        x, v, w = body_state(t)
        for row, gid in enumerate(a["gid"]):
            gid = int(gid)
            check(np.allclose(points[row], x[gid], rtol=0, atol=TOL), f"bodies t={t}: position of body {gid}")
            check(np.allclose(a["velocity"][row], v[gid], rtol=0, atol=TOL), f"bodies t={t}: velocity of body {gid}")
            check(np.allclose(a["angular_velocity"][row], w[gid], rtol=0, atol=TOL),
                  f"bodies t={t}: angular velocity of body {gid}")
            check(np.allclose(a["orientation"][row], orientation[gid], rtol=0, atol=TOL),
                  f"bodies t={t}: orientation (user frame) of body {gid}: {a['orientation'][row]}")
            check(int(a["shape_id"][row]) == (1 if gid == 1 else 2), f"bodies: shape_id of body {gid}")
            check(int(a["group_id"][row]) == (1 if gid == 1 else 2), f"bodies: group_id of body {gid}")


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "output"
    check_surfaces(out + "/surfaces.xmf")
    check_bodies(out + "/bodies.xmf")
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("XDMF output reads as expected with vtkXdmfReader")
    return 0


if __name__ == "__main__":
    sys.exit(main())
