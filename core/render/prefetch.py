"""``prefetch(a, i)``: a cache hint for row ``i`` of array ``a`` inside numba kernels.

The per-pixel kernels chase two dependent pointers per pixel (face id -> vertex ids -> vertex
data). With a million faces these rows live in L3 or DRAM, and one heavy pixel at a time leaves
the CPU waiting on each miss in turn. Asking for rows a few pixels ahead overlaps the misses.
A hint only: it never faults (out-of-range addresses are never formed, callers clamp) and never
changes a result.
"""
from __future__ import annotations

from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def prefetch(typingctx, arr, idx):
    """Read hint for ``arr[idx, 0, ...]`` (keep in all cache levels)."""
    if not isinstance(arr, types.Array) or not isinstance(idx, types.Integer):
        return None
    sig = types.void(arr, idx)

    def codegen(context, builder, signature, args):
        aty, ity = signature.args
        ary = context.make_array(aty)(context, builder, args[0])
        zero = context.get_constant(types.intp, 0)
        inds = [context.cast(builder, args[1], ity, types.intp)] + [zero] * (aty.ndim - 1)
        ptr = cgutils.get_item_pointer2(context, builder, ary.data, cgutils.unpack_tuple(builder, ary.shape),
                                        cgutils.unpack_tuple(builder, ary.strides), aty.layout, inds)
        i8p, i32 = ir.IntType(8).as_pointer(), ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0")
        # (address, read, locality 3 = keep in all levels, data cache)
        builder.call(fn, [builder.bitcast(ptr, i8p), ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return sig, codegen


FACE_AHEAD, VERTS_AHEAD = 16, 8
"""How many pixels ahead along an image row ``ahead`` fetches a face's row and its vertices' rows."""


@njit(inline="always")
def ahead(row, faces, verts, c):
    """Prefetch the face row of pixel c + FACE_AHEAD of a face-id image row and the rows of
    ``verts`` of pixel c + VERTS_AHEAD's vertices (its face row was fetched earlier)."""
    n = row.shape[0]
    if c + FACE_AHEAD < n:
        f = row[c + FACE_AHEAD]
        if f >= 0:
            prefetch(faces, f)
    if c + VERTS_AHEAD < n:
        f = row[c + VERTS_AHEAD]
        if f >= 0:
            prefetch(verts, faces[f, 0])
            prefetch(verts, faces[f, 1])
            prefetch(verts, faces[f, 2])
