"""Fused multiply-add in compiled code: ``fma(a, b, c)`` = a * b + c rounded once (LLVM's ``llvm.fma``).

numpy's matrix products of float64 go to BLAS, whose kernels (OpenBLAS on x86-64 with FMA) sum each entry as
``fma(a2, b2, fma(a1, b1, a0 * b0))``. A numba kernel that must give the same bits as such a product (a row times a
3x3 matrix, say) writes its sums with :func:`fma` in that order; the tests compare against numpy on the machine
they run on.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic


@intrinsic
def fma(typingctx, a, b, c):  # pragma: no cover - compiled
    """a * b + c (float64) rounded once, for numba-compiled code."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen
