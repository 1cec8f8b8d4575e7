"""Reading back the VTX files of a 2D run (``ale_xfem/output/vtx.py``) with ADIOS2's Python
bindings, into the serial numbering: each step's cell fields by the serial cell number
their ``cell`` field carries, and the nodal velocity and positions by the serial node
numbers their ``node`` field carries (a node in several ranks' blocks must carry the same
values in each)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

MESH_VARIABLES = {"NumberOfCells", "NumberOfNodes", "connectivity", "geometry", "step", "types", "vtkGhostType",
                  "vtkOriginalPointIds"}


def _adios2():
    """ADIOS2's Python bindings, loaded after DOLFINx: DOLFINx's wheel carries its own
    ADIOS2 libraries, which no longer load once the bindings' have (undefined symbols)."""
    import dolfinx_solver  # noqa: F401
    import dolfinx  # noqa: F401
    import adios2

    return adios2


def _blocks(stream, name):
    return [stream.read(name, block_id=b) for b in range(len(stream.all_blocks_info(name)[stream.current_step()]))]


def _by_node(ids, values, rtol=0.0):
    """Values of each block's points (``ids``: their serial node numbers, block by block)
    → one row per serial node; a node in several blocks must have the same values in each
    (within ``rtol`` of the largest: the writer computes each block's point coordinates
    from its cells, to the last bit or so)."""
    ids = np.concatenate([i.ravel() for i in ids]).astype(np.int64)
    values = np.concatenate([v.reshape(v.shape[0], -1) for v in values])
    out = np.full((ids.max() + 1, values.shape[1]), np.nan)
    out[ids] = values
    assert np.allclose(out[ids], values, rtol=0.0, atol=rtol * np.abs(values).max()), \
        "a node shared by two blocks has two values"
    return out


def read_cells(path: Path) -> list[dict]:
    """Each step of ``<name>-cells.bp``: {"time", "blocks", "cell_nodes" (n_cells, k) each
    cell's nodes, "position" (n_nodes, 3) the mesh's nodes, and each cell field (n_cells,),
    in the serial numbering}; every cell once."""
    adios2 = _adios2()
    steps = []
    with adios2.Stream(str(path), "r") as stream:
        for _ in stream.steps():
            fields = {name: np.concatenate([b.ravel() for b in _blocks(stream, name)])
                      for name in stream.available_variables() if name not in MESH_VARIABLES}
            cell = fields["cell"].astype(np.int64)
            assert np.array_equal(np.sort(cell), np.arange(cell.size)), "each cell once"
            step = {name: np.empty_like(values) for name, values in fields.items()}
            for name, values in fields.items():
                step[name][cell] = values
            step["time"] = float(stream.read("step"))
            step["blocks"] = len(_blocks(stream, "cell"))
            # each cell's nodes (serial numbers, VTK's order): the connectivity's rows (a
            # count, then the block's points) through the block's original point ids
            ids = [i.ravel().astype(np.int64) for i in _blocks(stream, "vtkOriginalPointIds")]
            rows = np.concatenate([i[c.reshape(c.shape[0], -1)[:, 1:]] for i, c in zip(ids, _blocks(stream, "connectivity"))])
            step["cell_nodes"] = np.empty_like(rows)
            step["cell_nodes"][cell] = rows
            step["position"] = _by_node(ids, _blocks(stream, "geometry"))
            steps.append(step)
    return steps


def read_velocity(path: Path) -> list[dict]:
    """Each step of ``<name>-velocity.bp``: {"time", "blocks", "position" (n_nodes, 3),
    "velocity" (n_nodes, 3)}, by serial node; every node at least once.  The positions are
    those the writer computes for each block's points (the P1 dofs' coordinates), which may
    differ from the mesh's in the last bit."""
    adios2 = _adios2()
    steps = []
    with adios2.Stream(str(path), "r") as stream:
        for _ in stream.steps():
            nodes = [np.rint(b.ravel()).astype(np.int64) for b in _blocks(stream, "node")]
            step = {"time": float(stream.read("step")), "blocks": len(nodes),
                    "position": _by_node(nodes, _blocks(stream, "geometry"), rtol=1e-15),
                    "velocity": _by_node(nodes, _blocks(stream, "velocity"))}
            assert not np.isnan(step["position"]).any(), "every node"
            steps.append(step)
    return steps
