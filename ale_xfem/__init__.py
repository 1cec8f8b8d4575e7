"""ale_xfem: multi-material ALE with enriched mixed cells on FEniCSx (Folzan, Le Tallec & Perlat 2011)."""

import hashlib
import os
from pathlib import Path

__version__ = "0.1.0"

# One BLAS thread.  The per-step work is compiled loops and numpy's element-wise kernels,
# which are single-threaded; what BLAS remains on a step's path (a wall's normal component
# in the 2D remap, `normal @ u`) is a product of a few hundred numbers, which OpenBLAS's
# default threads made slower, not faster: np.dot of 10⁵ doubles took 4–8 ms with them on a
# loaded two-core machine against 26 µs with one.  Set before numpy is first imported (the
# command line imports this package first); a value already in the environment is kept.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

# The compiled kernels (numba, cache=True) are cached in a folder named after the source of
# every module that holds kernels.  numba checks a cached kernel against its own file only:
# a kernel that inlines another file's (the fused loop inlines the equations of state) would
# otherwise keep the old code after that file changed.  The folder is the user's cache
# (XDG_CACHE_HOME, or ~/.cache), or NUMBA_CACHE_DIR if set, so a read-only install works.
KERNEL_SOURCES = ("ale_xfem/eos/kernels.py", "ale_xfem/model/cell_kernels.py", "ale_xfem/lagrange/kernels.py",
                  "ale_xfem/lagrange/interval_steps.py", "ale_xfem/mixed/cut_cells_2d.py",
                  "ale_xfem/mixed/equilibrium.py", "ale_xfem/mixed/closure_kernels.py",
                  "ale_xfem/mixed/enriched_steps.py", "ale_xfem/remap/swept_kernels.py",
                  "ale_xfem/remap/swept_kernels_2d.py", "ale_xfem/geometry/polygon_kernels.py",
                  "ale_xfem/model/plic.py", "forms/cut_quadrature.py")


# How LLVM compiles them.  A loop that reads and writes many arrays vectorises only where
# the compiler may test, once before the loop, that the arrays do not overlap; LLVM allows 8
# such tests by default, far fewer than a quadrilateral's state from its stored geometry
# needs (ale_xfem.lagrange.kernels.evaluate_one_gas_quadrilaterals, some twenty arrays; such
# a loop took 0.89 ms at 10⁵ cells as a scalar loop and 0.47 ms vectorised, measured alone;
# it vectorises from a threshold between 256 and 512).  Vectorising element-wise arithmetic
# changes no result: without fast-math LLVM neither reassociates nor contracts.  The
# setting is LLVM's, for every numba function the process compiles; it is set before any
# kernel is compiled, and is part of the cache folder's name.
LLVM_OPTIONS = ("-runtime-memory-check-threshold=1024", "-vectorize-memory-check-threshold=1024")


def _kernel_cache_folder() -> Path:
    root = Path(__file__).resolve().parent.parent
    digest = hashlib.sha256(__version__.encode())
    digest.update(" ".join(LLVM_OPTIONS).encode())
    for name in KERNEL_SOURCES:
        path = root / name
        digest.update(path.read_bytes() if path.exists() else name.encode())
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "ale_xfem")
    return Path(base) / f"kernels-{digest.hexdigest()[:16]}"


def _use_kernel_cache() -> None:
    import llvmlite.binding
    import numba

    numba.config.CACHE_DIR = str(_kernel_cache_folder())
    for option in LLVM_OPTIONS:
        llvmlite.binding.set_option("ale_xfem", option)


_use_kernel_cache()
