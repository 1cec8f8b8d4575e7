"""The closure of each set of mixed cells a run meets, by ``interface.model``: one closure
per model, kept for the whole run (a remap that makes new mixed cells rebinds it, so the
assembled predictor's forms compile once)."""

from __future__ import annotations

from ale_xfem.lagrange.closure import MixedCellClosure
from ale_xfem.mixed.enriched import EnrichedClosure
from ale_xfem.mixed.enriched_2d import EnrichedClosure2D
from ale_xfem.mixed.single_velocity import SingleVelocityClosure
from ale_xfem.model.mixed_cells import MixedCells

CLOSURES = {"enriched": EnrichedClosure, "single_velocity": SingleVelocityClosure}


class Closures:
    """Called with the current mixed cells, returns their closure.  ``assembled_predictor``:
    the enriched closure solves its predictor from the UFL forms, with the KSP options
    ``petsc_options`` (None: a direct solve)."""

    def __init__(self, mesh, materials, assembled_predictor: bool = False, petsc_options: dict | None = None,
                 stabilisation: str = "bubble", slip: str = "free", nitsche_penalty: float = 1.0,
                 normal: str = "youngs", ghost_viscosity: float | None = None):
        self.mesh, self.materials = mesh, materials
        self.assembled_predictor = assembled_predictor
        self.petsc_options = petsc_options
        # 2D enriched cells: their stabilisation, slip, Nitsche factor, PLIC's normals and
        # the weight of their ghost viscosity
        self.enriched_2d_options = dict(stabilisation=stabilisation, slip=slip, nitsche_penalty=nitsche_penalty,
                                        normal=normal, ghost_viscosity=ghost_viscosity)
        self.made = {}  # model → its closure
        # what binds an enriched closure's assembled system to its cells (None: its own
        # InterfaceSystem; on several MPI ranks, possibly one shared out over them)
        self.interface_system = None

    def __call__(self, mixed: MixedCells) -> MixedCellClosure:
        closure = self.made.get(mixed.model)
        if closure is not None:
            closure.bind(mixed)
            return closure
        if mixed.model == "enriched" and self.mesh.dimension == 2:
            closure = self.enriched_2d(mixed)
        else:
            options = ({"assembled": self.assembled_predictor, "petsc_options": self.petsc_options,
                        "system": self.interface_system} if mixed.model == "enriched" else {})
            closure = CLOSURES[mixed.model](self.mesh, self.materials, mixed, **options)
        self.made[mixed.model] = closure
        return closure

    def enriched_2d(self, mixed: MixedCells) -> MixedCellClosure:
        """The closure of 2D enriched cells (its forms compiled here, once per run)."""
        return EnrichedClosure2D(self.mesh, self.materials, mixed, petsc_options=self.petsc_options,
                                 **self.enriched_2d_options)
