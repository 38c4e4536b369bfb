"""Arrays at an address, for compiled code: the one numba internal the engine's hand-offs use.

The compiled entry points that C calls take a single integer, the address of a table of
array addresses and shapes (`native`, `setup`); `array_at` makes a C-contiguous array of
such an address inside compiled code without numba's runtime (no allocation, no reference
count); with `word` and `dims` also a 2-D view of part of a flat buffer (numpy's reshape
would call a helper of numba's runtime library, which an engine linked into a C program
does not have). A compiled function returns no array it did not get (numba's rule without
its runtime), so the view is made where it is used.
It builds the array with numba's own code generation (`numba.np.arrayobj.make_array`,
`populate_array`, `numba.core.cgutils.unpack_tuple`), the internals that
`tests/test_compile_structure.py` names if they go missing.
"""

from __future__ import annotations

import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

from ..jitcache import jit_hot

INTERNALS = ("numba.np.arrayobj.make_array", "numba.np.arrayobj.populate_array",
             "numba.core.cgutils.unpack_tuple", "numba.extending.intrinsic")


@intrinsic
def array_at(typingctx, address, shape, proto):
    """The C-contiguous array at the int64 ``address`` with the dimensions ``shape`` (a
    tuple of int64) and the type of the scalar ``proto`` (0.0: float64, 0: int64). It owns
    nothing (no reference count: the engine holds the memory)."""
    dtype = types.unliteral(proto)
    ndim = len(shape)
    arrty = types.Array(dtype, ndim, "C")
    sig = arrty(address, shape, proto)

    def codegen(context, builder, signature, args):
        addr, shp, _ = args
        ary = make_array(arrty)(context, builder)
        itemsize = context.get_abi_sizeof(context.get_data_type(dtype))
        dims = cgutils.unpack_tuple(builder, shp, ndim)
        strides = [context.get_constant(types.intp, itemsize)]
        for d in reversed(dims[1:]):
            strides.insert(0, builder.mul(strides[0], d))
        populate_array(ary, data=builder.inttoptr(addr, ary.data.type), shape=dims,
                       strides=strides, itemsize=context.get_constant(types.intp, itemsize),
                       meminfo=None)
        return ary._getvalue()

    return sig, codegen


@jit_hot
def word(buf, offset):
    """The address of word ``offset`` of the float64 buffer ``buf`` (for `array_at`: a
    view of part of it, which the caller keeps alive)."""
    return buf.ctypes.data + 8 * offset


@jit_hot
def dims(rows, cols):
    """A 2-D shape as `array_at` takes it."""
    return np.int64(rows), np.int64(cols)
