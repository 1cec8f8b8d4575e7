"""A linear system of compiled forms bound to one mesh (a submesh around the mixed cells):
its matrix and vectors created once, refilled and solved at every call (the forms made
again, without compiling, when the cells integrated over change; the KSP made again when
the operator does: a constrained system Cᵀ A C with a new C) — what the systems of
:mod:`forms.enriched_interface` (and any other forms of a mixed-cell submesh) rely on."""

from __future__ import annotations

import itertools

import numba
import numpy as np

import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
import dolfinx
import dolfinx.fem.petsc
import ufl.algorithms
from petsc4py import PETSc

REFINEMENTS = 3  # rounds of iterative refinement after the direct solve
# An operator whose diagonal is within REUSE_CHANGE (relative) of the one last factorised is
# solved on those factors, refined until every row's residual is within REUSE_BACKWARD_ERROR
# of the row's scale Σ_j |A_ij x_j| + |b_i| (a componentwise backward error: the rows differ
# by twenty orders of magnitude, held velocities against pressures), in at most REUSE_ROUNDS
# rounds; otherwise it is factorised
REUSE_CHANGE, REUSE_BACKWARD_ERROR, REUSE_ROUNDS = 0.02, 1e-14, 12
_PREFIXES = itertools.count()  # each system's own options prefix


def every_rank(comm, flag) -> bool:
    """Whether ``flag`` holds on every rank of ``comm`` (what a decision that leads into a
    collective call must be: all ranks take it, or none); one rank's own flag on one."""
    if comm.size == 1:
        return bool(flag)
    from mpi4py import MPI

    return comm.allreduce(bool(flag), op=MPI.LAND)


def largest_over_ranks(comm, value: float) -> float:
    """The largest of every rank's ``value`` (its own on one rank)."""
    if comm.size == 1:
        return value
    from mpi4py import MPI

    return comm.allreduce(value, op=MPI.MAX)


def petsc_reason(error) -> str:
    """The one line of a PETSc error that says why (its message is a traceback, one frame a
    line, the reason last)."""
    lines = str(error).strip().splitlines()
    return lines[-1].removeprefix("[0]").strip() if lines else str(error)


def keep_factor_solver(preconditioner, factor_solver: str | None, options) -> None:
    """A ``pc_type`` among the options that changes the factorisation (``lu`` for the
    default ``cholesky``) makes PETSc forget the factor solver set before: set it again,
    unless the options choose one (``pc_factor_mat_solver_type``)."""
    if (factor_solver is not None and preconditioner.getType() in ("lu", "cholesky")
            and "pc_factor_mat_solver_type" not in dict(options)):
        preconditioner.setFactorSolverType(factor_solver)


@numba.njit(cache=True)
def galerkin_product(a_pointer, a_columns, a_values, c_pointer, c_columns, c_values, n):  # pragma: no cover (compiled)
    """Cᵀ A C in CSR (pointer, columns, values) from A (N × N) and C (N × ``n``) in CSR:
    the sums of a row-by-row sparse-axpy PtAP, in its order (as PETSc's SparseAxpy
    algorithm writes them): (A C)_iq = Σ_j a_ij c_jq over A's row i in order, then
    (Cᵀ A C)_pq = Σ_i c_ip (A C)_iq over the rows i in increasing order, each sum from +0 —
    but only over the rows C keeps (a row of C with no entry adds nothing).  The pattern and
    the bits are those of this PETSc's sequential PtAP (tests/test_enriched_2d.py compares
    them, with joined unknowns and coefficients other than 1).  Columns in increasing order
    in each row.  (The two sparse accumulations are written
    out: through a shared compiled helper the product took three times as long.)"""
    rows = a_pointer.size - 1
    # A C, over the rows C keeps
    bound = 0
    for i in range(rows):
        if c_pointer[i + 1] > c_pointer[i]:
            for t in range(a_pointer[i], a_pointer[i + 1]):
                bound += c_pointer[a_columns[t] + 1] - c_pointer[a_columns[t]]
    ac_pointer = np.zeros(rows + 1, dtype=np.int64)
    ac_columns = np.empty(bound, dtype=np.int64)
    ac_values = np.empty(bound)
    dense = np.zeros(n)
    seen = np.full(n, -1, dtype=np.int64)
    count = 0
    for i in range(rows):
        start = count
        if c_pointer[i + 1] > c_pointer[i]:
            for t in range(a_pointer[i], a_pointer[i + 1]):
                j = a_columns[t]
                for s in range(c_pointer[j], c_pointer[j + 1]):
                    q = c_columns[s]
                    if seen[q] != i:
                        seen[q] = i
                        dense[q] = 0.0
                        ac_columns[count] = q
                        count += 1
                    dense[q] += a_values[t] * c_values[s]
            for t in range(start, count):
                ac_values[t] = dense[ac_columns[t]]
        ac_pointer[i + 1] = count
    # Cᵀ by rows: for each column p of C, the rows i that hold it, in increasing order
    t_pointer = np.zeros(n + 1, dtype=np.int64)
    for s in range(c_columns.size):
        t_pointer[c_columns[s] + 1] += 1
    for p in range(n):
        t_pointer[p + 1] += t_pointer[p]
    t_rows = np.empty(c_columns.size, dtype=np.int64)
    t_values = np.empty(c_columns.size)
    fill = t_pointer[:-1].copy()
    for i in range(rows):
        for s in range(c_pointer[i], c_pointer[i + 1]):
            p = c_columns[s]
            t_rows[fill[p]] = i
            t_values[fill[p]] = c_values[s]
            fill[p] += 1
    # Cᵀ (A C), row by row
    pointer = np.zeros(n + 1, dtype=np.int64)
    columns = np.empty(count, dtype=np.int64)  # (at most A C's entries)
    values = np.empty(count)
    seen[:] = -1
    filled = 0
    for p in range(n):
        start = filled
        for r in range(t_pointer[p], t_pointer[p + 1]):
            i = t_rows[r]
            for t in range(ac_pointer[i], ac_pointer[i + 1]):
                q = ac_columns[t]
                if seen[q] != p:
                    seen[q] = p
                    dense[q] = 0.0
                    columns[filled] = q
                    filled += 1
                dense[q] += t_values[r] * ac_values[t]
        for t in range(start + 1, filled):  # a row's few columns in increasing order
            key = columns[t]
            u = t - 1
            while u >= start and columns[u] > key:
                columns[u + 1] = columns[u]
                u -= 1
            columns[u + 1] = key
        for t in range(start, filled):
            values[t] = dense[columns[t]]
        pointer[p + 1] = filled
    return pointer, columns[:filled].copy(), values[:filled].copy()


@numba.njit(cache=True)
def row_scales(pointer, columns, values, x, b):  # pragma: no cover (compiled)
    """Σ_j |A_ij x_j| + |b_i| for each row i of A in CSR (``pointer``, ``columns``,
    ``values``): the scale of the componentwise backward error, each row's sum from +0 over
    its entries in order (np.bincount's order and bits)."""
    rows = pointer.size - 1
    scale = np.empty(rows)
    for i in range(rows):
        total = 0.0
        for t in range(pointer[i], pointer[i + 1]):
            total += np.abs(values[t]) * np.abs(x[columns[t]])
        scale[i] = total + np.abs(b[i])
    return scale


class FormBinder:
    """A compiled form (dolfinx.fem.compile_form) made into forms over chosen cells, again
    and again, without compiling: what dolfinx.fem.create_form makes, with the coefficients
    looked up in the UFL form once (create_form walks the UFL expression at every call —
    about 2 ms a step of a 2D enriched run at 200², whose forms follow the mixed cells)."""

    def __init__(self, compiled, spaces, mesh, coefficient_map, constant_map=None):
        self._compiled, self._mesh = compiled, mesh
        self._spaces = [space._cpp_object for space in spaces]
        ufcx = compiled.ufcx_form
        original = ufl.algorithms.extract_coefficients(compiled.ufl_form)
        self._coefficients = {}
        for c in range(ufcx.num_coefficients):
            coefficient = original[ufcx.original_coefficient_positions[c]]
            if coefficient not in coefficient_map:
                raise RuntimeError(f"FormBinder: missing coefficient {coefficient}")
            self._coefficients[f"w{c}"] = coefficient_map[coefficient]._cpp_object
        constants = ufl.algorithms.analysis.extract_constants(compiled.ufl_form)
        if ufcx.num_constants != len(constants):
            raise RuntimeError(f"FormBinder: {ufcx.num_constants} constants compiled, {len(constants)} in the form")
        constant_map = constant_map or {}
        if any(constant not in constant_map for constant in constants):
            raise RuntimeError(f"FormBinder: missing constants of {constants}")
        self._constants = {f"c{i}": constant_map[constant]._cpp_object for i, constant in enumerate(constants)}
        self._create = dolfinx.fem.forms.form_cpp_creator(compiled.dtype)
        self._address = compiled.module.ffi.cast("uintptr_t", compiled.module.ffi.addressof(ufcx))

    def over(self, subdomains) -> dolfinx.fem.Form:
        """The form over ``subdomains`` (dolfinx.fem.create_form's: integral type → [(id,
        entities)])."""
        data = {kind: sorted(domains, key=lambda domain: domain[0]) for kind, domains in subdomains.items()}
        form = self._create(self._address, self._spaces, self._coefficients, self._constants, data, [],
                            self._mesh._cpp_object)
        return dolfinx.fem.Form(form, self._compiled.ufcx_form, self._compiled.code)


class BoundSystem:
    """``compiled_bilinear`` and ``compiled_linear`` (dolfinx.fem.compile_form) bound to
    ``space`` on ``mesh`` with ``coefficient_map`` (abstract coefficient → Function); a
    direct solve (``factor_solver``: PETSc's own when None), LU or, for ``symmetric`` forms,
    LDLᵀ, whose KSP options can be overridden by ``petsc_options``."""

    def __init__(self, compiled_bilinear, compiled_linear, space, mesh, coefficient_map,
                 factor_solver: str | None = None, petsc_options: dict | None = None, subdomains=None,
                 symmetric: bool = False):
        self._compiled = (compiled_bilinear, compiled_linear)
        self._symmetric = symmetric
        self._comm = mesh.comm
        self._parallel = mesh.comm.size > 1  # a mesh shared out over MPI ranks: rows on each
        self._space, self._mesh, self._coefficients = space, mesh, coefficient_map
        self._binders = None  # (FormBinder of the bilinear form, of the linear one)
        self.integrate_over(subdomains or {})
        self.matrix = dolfinx.fem.petsc.create_matrix(self.bilinear)
        # PETSc keeps of the preallocated pattern only the entries its first assembly sets,
        # and later assemblies over other cells could not add theirs: set them all now (the
        # forms' values do not matter, only where they are)
        dolfinx.fem.petsc.assemble_matrix(self.matrix, self.bilinear)
        self.matrix.assemble()
        self._mark_symmetric(self.matrix)
        self.vector = dolfinx.fem.petsc.create_vector(space)
        self.solution = self.matrix.createVecRight()
        self.residual = self.matrix.createVecRight()
        self.correction = self.matrix.createVecRight()
        self._factor_solver, self._petsc_options = factor_solver, dict(petsc_options or {})
        self.solver, self._operator, self._options = None, None, []
        self._reduced, self._constraint = (), None
        self._constraint_pattern = None  # (the CSR pointer and columns of that constraint)
        self._selection = None  # (a constraint, the unknowns it selects or None: _reduce)
        self._factored = None  # (the operator last factorised, its diagonal then)
        self._make_solver()

    def _make_solver(self) -> None:
        """A new KSP (a factorisation cannot change its operator's size: a new one when the
        constrained system's size changes) with the system's options."""
        if self.solver is not None:
            self.solver.destroy()
        self.solver = PETSc.KSP().create(self._mesh.comm)
        self.solver.setOperators(self.matrix)
        self.solver.setType("preonly")
        # a symmetric operator (symmetric forms, and C^T A C of them): LDL^T (MUMPS pivots
        # the indefinite rows in 2 x 2 blocks), half the factors of LU
        self.solver.getPC().setType("cholesky" if self._symmetric else "lu")
        if self._factor_solver is not None:
            self.solver.getPC().setFactorSolverType(self._factor_solver)
        # the options stay in PETSc's database until this KSP's first solve has read them (its
        # factorisation reads its own then), then leave it: a factorisation of another
        # operator (a new C) would not find them, so a new operator gets a new KSP
        self._options = []
        if self._petsc_options:
            prefix = f"ale_xfem_system_{next(_PREFIXES)}_"
            self.solver.setOptionsPrefix(prefix)
            database = PETSc.Options()
            for key, value in self._petsc_options.items():
                database[prefix + key] = value
                self._options.append(prefix + key)
            try:
                self.solver.setFromOptions()
            except PETSc.Error as error:
                self._forget_options()
                raise RuntimeError(f"PETSc options {self._petsc_options}: {petsc_reason(error)}") from None
            keep_factor_solver(self.solver.getPC(), self._factor_solver, self._petsc_options)

    def integrate_over(self, subdomains) -> None:
        """(Re-)create the forms over ``subdomains`` (dolfinx.fem.create_form's: integral type
        → [(id, entities)]) — without compiling; the matrix keeps the pattern of the forms the
        system was created with, which must cover them."""
        if self._binders is None:
            bilinear, linear = self._compiled
            space, mesh, coefficients = self._space, self._mesh, self._coefficients
            self._binders = (FormBinder(bilinear, [space, space], mesh, coefficients),
                             FormBinder(linear, [space], mesh, coefficients))
        self.bilinear, self.linear = (binder.over(subdomains) for binder in self._binders)

    def assemble(self):
        """Assemble the matrix and the forms' right side; returns the right side's array
        (writable: explicit terms are added to it, then :meth:`solve`)."""
        self.matrix.zeroEntries()
        dolfinx.fem.petsc.assemble_matrix(self.matrix, self.bilinear)
        self.matrix.assemble()
        with self.vector.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.assemble_vector(self.vector, self.linear)
        if self._parallel:  # the ghost entries' contributions to their owners' rows
            self.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return self.vector.getArray(readonly=False)

    def solve(self, right_side, what: str, constraint=None):
        """Solve with ``right_side`` (the array of :meth:`assemble`, completed) and
        REFINEMENTS rounds of iterative refinement; returns the solution's array.  ``what``
        names the system in the error of a failed factorisation.  ``constraint``: a PETSc
        matrix C (n × r) whose columns span the admissible solutions, x = C y (unknowns
        that must be equal, exactly): the system solved is Cᵀ A C y = Cᵀ b.
        The same ``constraint`` object as the last solve's reuses the reduced matrix and its
        factorisation's analysis (only the values are new)."""
        self.vector.setArray(right_side)
        if constraint is None:
            self._solve(self.matrix, self.vector, self.solution, self.residual, self.correction, what)
            return self.solution.getArray()
        if constraint is self._constraint:
            self._reduce(constraint, self._reduced[0])
        else:
            self._forget_reduced()
            reduced = self._reduce(constraint)
            self._mark_symmetric(reduced)
            right = constraint.createVecRight()
            self._reduced = (reduced, right, right.duplicate(), right.duplicate(), right.duplicate())
            self._constraint = constraint
        reduced, right, solution, residual, correction = self._reduced
        constraint.multTranspose(self.vector, right)
        # the same unknowns as the last solve's, the operator barely changed (the corrector's
        # last iterations): refined on the last factors, if that converges
        if not self._refined_on_factors(reduced, right, solution, residual, correction):
            self._solve(reduced, right, solution, residual, correction, what)
        constraint.mult(solution, self.solution)
        return self.solution.getArray()

    def _diagonal_change(self, operator) -> float:
        """The largest relative change of ``operator``'s diagonal from the operator's last
        factorised (∞ when another operator was)."""
        if self._factored is None or self._factored[0] is not operator:
            return np.inf
        old, new = self._factored[1], operator.getDiagonal().array
        with np.errstate(divide="ignore", invalid="ignore"):  # (zero stays zero on multiplier rows)
            change = np.where(old == new, 0.0, np.abs(new / old - 1.0))
        change = float(np.max(change, initial=0.0))
        return largest_over_ranks(self._comm, change)

    def solve_with_diagonal(self, right_side, what: str, constraint, rows, diagonal):
        """Solve again the operator of the last :meth:`solve` (the same ``constraint``) with
        its diagonal entries at ``rows`` — unknowns of the full system that the constraint
        keeps as they are (a column of their own, coefficient 1) — set to ``diagonal``, and
        the right side ``right_side`` (full): neither assembled nor reduced again, the
        factorisation's analysis kept.  Returns the solution's array."""
        if constraint is not None and constraint is not self._constraint:
            raise RuntimeError(f"{what}: solve_with_diagonal needs the constraint of the last solve")
        self.vector.setArray(right_side)
        if constraint is None:
            operator, right, solution, residual, correction = (self.matrix, self.vector, self.solution,
                                                              self.residual, self.correction)
        else:
            operator, right, solution, residual, correction = self._reduced
            if self._constraint_pattern is None:  # (a kept constraint keeps its pattern)
                self._constraint_pattern = constraint.getValuesCSR()[:2]
            pointer, columns = self._constraint_pattern
            # their columns of C: their unknowns in the reduced system (this rank's, local)
            rows = columns[pointer[rows]] - constraint.getOwnershipRangeColumn()[0]
        entries = operator.getDiagonal()
        entries.array[rows] = diagonal
        operator.setDiagonal(entries)
        entries.destroy()
        if constraint is not None:
            constraint.multTranspose(self.vector, right)
        if not self._refined_on_factors(operator, right, solution, residual, correction):
            self._solve(operator, right, solution, residual, correction, what)
        if constraint is None:
            return self.solution.getArray()
        constraint.mult(solution, self.solution)
        return self.solution.getArray()

    def _refined_on_factors(self, operator, right, solution, residual, correction) -> bool:
        """Solve ``operator`` by iterative refinement on the factors of the last operator
        factorised, if it is the same matrix and its diagonal moved by at most REUSE_CHANGE;
        False if that does not hold or REUSE_ROUNDS rounds do not bring each row's residual
        within REUSE_BACKWARD_ERROR of its scale (then the caller factorises)."""
        if self._diagonal_change(operator) > REUSE_CHANGE:
            return False
        csr = None
        target = REUSE_BACKWARD_ERROR * right.norm()
        preconditioner = self.solver.getPC()
        preconditioner.setReusePreconditioner(True)  # the operator changed: keep its old factors
        try:
            solution.set(0.0)
            residual.setArray(right.getArray(readonly=True))
            for _ in range(REUSE_ROUNDS):
                self.solver.solve(residual, correction)
                solution.axpy(1.0, correction)
                operator.mult(solution, residual)
                residual.aypx(-1.0, right)
                if residual.norm() > target:  # (cheap: no row can be within its scale yet)
                    continue
                if csr is None:
                    csr = operator.getValuesCSR()
                x, b = self._whole(solution), right.getArray(readonly=True)
                scale = row_scales(*csr, x, b)
                if every_rank(self._comm, np.all(np.abs(residual.getArray(readonly=True))
                                                 <= REUSE_BACKWARD_ERROR * scale)):
                    return True
            return False
        finally:
            preconditioner.setReusePreconditioner(False)

    def _whole(self, vector) -> np.ndarray:
        """A vector's entries on every rank (its own on one)."""
        if not self._parallel:
            return vector.getArray(readonly=True)
        scatter, whole = PETSc.Scatter.toAll(vector)
        scatter.scatter(vector, whole, PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD)
        values = whole.getArray(readonly=True).copy()
        scatter.destroy()
        whole.destroy()
        return values

    def _reduce(self, constraint, result=None):
        """Cᵀ A C (into ``result``, made by the last call with this ``constraint``): where C
        only selects unknowns (each a column of its own, coefficient 1, in order: no unknowns
        joined) that is A's submatrix of the selected rows and columns, the same entries in
        the same places, made in a fifth of PtAP's time (2 against 10–12 ms for 5 000 of
        15 000 unknowns); where it joins unknowns, on one rank, :func:`galerkin_product`
        (PtAP's pattern and bits over the rows C keeps: about 2.5 against 4–5 ms), and on
        several, PETSc's PtAP."""
        fetched = None  # (C's CSR, when this call reads it)
        if self._selection is None or self._selection[0] is not constraint:
            fetched = constraint.getValuesCSR()
            pointer, columns, values = fetched
            self._constraint_pattern = (pointer, columns)
            rows = np.flatnonzero(np.diff(pointer) > 0)
            chosen = None
            first_row, first_column = constraint.getOwnershipRange()[0], constraint.getOwnershipRangeColumn()[0]
            selects = bool(rows.size == constraint.getLocalSize()[1] and np.all(np.diff(pointer) <= 1)
                           and np.array_equal(columns, first_column + np.arange(rows.size)) and np.all(values == 1.0))
            if every_rank(self._comm, selects):
                chosen = PETSc.IS().createGeneral((first_row + rows).astype(PETSc.IntType), comm=self._mesh.comm)
            self._forget_selection()
            self._selection = (constraint, chosen)
        chosen = self._selection[1]
        if chosen is not None:
            return self.matrix.createSubMatrix(chosen, chosen, submat=result)
        if self._parallel:
            return self.matrix.PtAP(constraint, result=result)
        # (C's values, not only A's, may be new: a kept constraint's are refreshed in place)
        a, c = self.matrix.getValuesCSR(), fetched if fetched is not None else constraint.getValuesCSR()
        n = constraint.getSize()[1]
        pointer, columns, values = galerkin_product(*a, *c, n)  # (PETSc's int32 indices, as they are)
        pointer, columns = pointer.astype(PETSc.IntType), columns.astype(PETSc.IntType)
        if result is None:  # (PETSc keeps the arrays, not a copy)
            return PETSc.Mat().createAIJWithArrays((n, n), (pointer, columns, values), comm=self._mesh.comm)
        result.setValuesCSR(pointer, columns, values)  # the same constraint: the same pattern
        result.assemble()
        return result

    def _forget_selection(self) -> None:
        if self._selection is not None and self._selection[1] is not None:
            self._selection[1].destroy()
        self._selection = None

    def _mark_symmetric(self, operator) -> None:
        """Tell PETSc that ``operator`` is symmetric, for as long as it lives (its values are
        refilled by symmetric forms), when the system's forms are."""
        if self._symmetric:
            operator.setOption(PETSc.Mat.Option.SYMMETRIC, True)
            operator.setOption(PETSc.Mat.Option.SYMMETRY_ETERNAL, True)

    def _forget_reduced(self) -> None:
        for thing in self._reduced:
            thing.destroy()
        self._reduced, self._constraint, self._constraint_pattern = (), None, None

    def _solve(self, operator, right, solution, residual, correction, what: str) -> None:
        # a factorisation cannot change its operator's size, and reads its options (the
        # scene's petsc_options, which have left PETSc's database) when it is made: a new
        # KSP for another operator than the last one
        if self._operator is not None and operator is not self._operator:
            self._make_solver()
        self._operator = operator
        self.solver.setOperators(operator)
        try:
            self.solver.solve(right, solution)
        except PETSc.Error as error:
            raise RuntimeError(f"{what}: {petsc_reason(error)}") from None
        finally:
            self._forget_options()
        reason = self.solver.getConvergedReason()
        if reason < 0:
            raise RuntimeError(f"{what}: the KSP failed (PETSc reason {reason})")
        self._factored = (operator, operator.getDiagonal().array.copy())  # (what _refined_on_factors compares)
        for _ in range(REFINEMENTS):
            operator.mult(solution, residual)
            residual.aypx(-1.0, right)
            self.solver.solve(residual, correction)
            solution.axpy(1.0, correction)

    def destroy(self) -> None:
        """Free the system's PETSc objects now.  On a mesh shared out over MPI ranks every
        rank calls it together: there garbage collection would only park them (PETSc frees
        a parallel object collectively), and a run that binds new systems would keep every
        old one's factors."""
        self._forget_reduced()
        self._forget_selection()
        self._factored, self._operator = None, None
        for thing in (self.solver, self.matrix, self.vector, self.solution, self.residual, self.correction):
            thing.destroy()
        self._forget_options()

    def _forget_options(self) -> None:
        database = PETSc.Options()
        for name in self._options:
            database.delValue(name)
        self._options = []
