"""The private runtime corner: what every layer may use and no user needs.

Input validation (:mod:`.validate`), evaluation of CasADi functions into NumPy
buffers (:mod:`.buffered`), C compilation of CasADi functions and its cache
(:mod:`.compiled`), the terminal (:mod:`.console`: logging and progress bars)
the large-block allocator (:mod:`.allocator`) and workers that end with the
process they work for (:mod:`.lifeline`).  No physics and no imports
from the rest of the package.
"""

import time

#: When this process imported the package (``time.time_ns()``; the package's
#: ``__init__`` imports this module first): compiled kernels are found by a hash
#: of the source only if no source file changed since
#: (:func:`morphoshell.numerics.cell_kernels.compiled_cell_functions`).
IMPORTED_NS = time.time_ns()
