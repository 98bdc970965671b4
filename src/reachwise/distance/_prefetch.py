"""A cache hint for the compiled kernels of :mod:`reachwise.distance`.

:func:`prefetch_for_write` asks the processor to bring the cache line of one array
element into the cache, ready to be written, without waiting for it: a kernel that
knows which scattered elements it writes next (the voxels of the next image row in
:func:`~reachwise.distance._memory_kernel.mark_points`) hides the memory's latency
behind the work it does now. It is LLVM's ``llvm.prefetch`` intrinsic (write intent,
high locality, data cache), which numba does not expose; a hint changes no value and
never faults, whatever the address.
"""

from __future__ import annotations

from typing import Any

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

#: ``llvm.prefetch``'s arguments after the address: write (1), keep in every cache
#: level (locality 3), data cache (1).
_WRITE, _LOCALITY, _DATA = 1, 3, 1


@intrinsic
def prefetch_for_write(typingctx: Any, array: Any, index: Any) -> Any:
    """In a compiled kernel, ``prefetch_for_write(array, index)`` hints that
    ``array.flat[index]`` (a C-contiguous one-dimensional ``array``, any integer
    ``index``, not bounds-checked: a hint past the end changes nothing) is written
    soon. Returns nothing."""
    sig = types.void(array, index)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        array_type = signature.args[0]
        view = context.make_array(array_type)(context, builder, args[0])
        pointer = cgutils.get_item_pointer(
            context, builder, array_type, view, [args[1]], wraparound=False
        )
        byte_pointer = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        hint = builder.module.declare_intrinsic(
            "llvm.prefetch",
            [byte_pointer],
            ir.FunctionType(ir.VoidType(), [byte_pointer, i32, i32, i32]),
        )
        builder.call(
            hint,
            [builder.bitcast(pointer, byte_pointer), i32(_WRITE), i32(_LOCALITY), i32(_DATA)],
        )
        return context.get_dummy_value()

    return sig, codegen
