"""Borrowed views of records for the per-node loops: arrays that numba does not reference-count.

numba counts references to every array a kernel binds: an atomic add on the array's MemInfo each time a
helper with a branch binds it, and another when it lets go. On the records a render reads (the scene, the
quadrature rule, a thread's work arrays) those pairs took 25-41 % of a lit render (docs/performance.md,
"Choices in the kernels that buy speed"). A borrowed view is the same array (data, shape, strides) without a MemInfo: NRT then skips it.

A borrowed view must not outlive its owner. The scene records and the quadrature outlive every kernel
that reads them (the caller holds them for the whole call). A thread's work arrays are held by the
RayWork that ``alloc_ray_work`` returned (``own``) until the end of the kernel; when a ray grows the
sweep scratch or the ray pieces, the grown record is an owned one, which ``hold_grown`` hands to ``own``
before it borrows it.
"""
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from .config import NJIT_INLINE
from .records import RayWork
from .sweep import capacity_of


def _borrowable(typ):
    if isinstance(typ, types.Array):
        return True
    if isinstance(typ, types.BaseTuple):
        return all(_borrowable(t) for t in typ)
    return isinstance(typ, (types.Number, types.Boolean, types.NoneType))


def _borrow_value(context, builder, typ, value):
    if isinstance(typ, types.Array):
        src = context.make_array(typ)(context, builder, value=value)
        out = context.make_array(typ)(context, builder)
        cgutils.copy_struct(out, src)
        out.meminfo = cgutils.get_null_value(out.meminfo.type)
        out.parent = cgutils.get_null_value(out.parent.type)
        return out._getvalue()
    if isinstance(typ, types.BaseTuple):
        items = [_borrow_value(context, builder, t, builder.extract_value(value, i)) for i, t in enumerate(typ)]
        return context.make_tuple(builder, typ, items)
    return value


@intrinsic
def borrow(typingctx, rec):
    """rec (an array, or a record of arrays, records, numbers and None) with every array borrowed: the same
    data, shape and strides without a MemInfo, so reference counting skips them. It must not outlive rec."""
    if not _borrowable(rec):
        return None
    sig = rec(rec)

    def codegen(context, builder, signature, args):
        return _borrow_value(context, builder, signature.args[0], args[0])
    return sig, codegen


@njit(**NJIT_INLINE)
def hold_grown(own, work):
    """After a ray: if it grew the sweep scratch or the ray pieces (work holds an owned, bigger record),
    ``own`` takes the grown record, and work borrows it. Returns (own, work)."""
    scratch = own.scratch
    if capacity_of(work.scratch) != capacity_of(own.scratch):
        scratch = work.scratch
    pieces = own.pieces
    if work.pieces.t0.shape[0] != own.pieces.t0.shape[0]:
        pieces = work.pieces
    own = RayWork(scratch, pieces, own.cand, own.stack, own.nodes)
    return own, borrow(own)


@njit(**NJIT_INLINE)
def release(own):
    """The last use of ``own`` (a records.RayWork): numba frees a record after its last use, so a kernel
    that borrows its arrays calls this after its loops."""
    own.nodes.count[0] += 0.0  # a use LLVM keeps (x + 0.0 is not x for x = -0.0)
