"""
The Newmark step's operands that do not change from step to step, as one compiled object.

numba unboxes every array of a tuple argument at every call: the step's forces, operators and
work arrays are about 150 arrays, and their unboxing cost about 8 us of the mean model's
110 us step. Held in one StructRef they are unboxed as a single pointer (0.7 us for 90
arrays against 5.9 us as tuples, measured). The fields are the tuples themselves
(``newmark_kernel.step`` reads them by name), so the kernels that take the tuples are
unchanged; the integrator rebuilds the object when one of them is replaced (a new batch
size, new germs or law factors). The arrays are shared, not copied: a state array written
from Python (the top-drive angle of the imbalance or of the lobes) is seen by the step.
"""
from __future__ import annotations

from numba.core import types
from numba.experimental import structref

from drill_twin.numerics.compiled import kernel


@structref.register
class StepOperandsType(types.StructRef):
    """numba type of :class:`StepOperands`."""

    def preprocess_fields(self, fields):
        """Keep the fields' types as they are (no literals)."""
        return tuple((name, types.unliteral(kind)) for name, kind in fields)


class StepOperands(structref.StructRefProxy):
    """
    (forces, operators, work, compact) of :func:`newmark_kernel.step`, as one object.

    forces: the arguments of forces.string_forces; operators: the step's operators and the
    law's constants; work: the work arrays of the batch; compact: the compacted iterations'
    buffers (see :func:`newmark_kernel.step`).
    """


structref.define_proxy(StepOperands, StepOperandsType,
                       ['forces', 'operators', 'work', 'compact'])


@kernel
def make_step_operands(forces, operators, work, compact):
    """
    Return a :class:`StepOperands` of the four tuples.

    Made in compiled code: the proxy's own constructor is compiled again in every process
    (3.5 s), this one is cached on disk with the kernels.
    """
    return StepOperands(forces, operators, work, compact)
