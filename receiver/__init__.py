"""gnssrx: a GNSS software receiver for recorded IF samples."""

import os as _os

__version__ = "0.1.0"

# BLAS on one thread, set before numpy loads (any entry point that imports this package first: the CLI,
# the batch workers, the figure scripts).  The receiver parallelises on its own threads (receiver/threads.py),
# so BLAS threads only oversubscribe the cores; and a threaded BLAS product (e.g. the fine-Doppler line
# powers' matrix products) sums in an order that depends on the thread count, which moved the last bit of an
# acquisition Doppler and, through a vector loop, whole figure results between -j 1 and -j 2.  A value set
# in the environment wins.
for _v in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
    _os.environ.setdefault(_v, "1")
del _v
