"""``borrow(a)``: inside a kernel, the array ``a`` without its reference count.

numba counts references to each array it got from Python: every assignment of an array to a
variable (an inlined helper's parameters included) increments and later decrements a shared
counter atomically. In a per-pixel loop that passes arrays to inlined helpers this costs more
than the arithmetic (5x on the silhouette pass), and threads working on the same arrays contend
for the counter's cache line. A borrowed array is the same view with no counter (as numba's own
``prange`` bodies get their arrays): the counting is then a test of a null pointer.

The caller keeps the original alive for the kernel's duration (it is an argument), so the
borrowed view must not outlive the call: never return or store it.
"""
from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def borrow(typingctx, arr):
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, sig, args):
        src = context.make_array(sig.args[0])(context, builder, args[0])
        dst = context.make_array(sig.return_type)(context, builder)
        for name in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(dst, name, getattr(src, name))
        dst.meminfo = cgutils.get_null_value(dst.meminfo.type)
        dst.parent = cgutils.get_null_value(dst.parent.type)
        return dst._getvalue()

    return arr(arr), codegen
