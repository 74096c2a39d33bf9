"""gnssrx: a GNSS software receiver for recorded IF samples."""

import os as _os

__version__ = "0.1.0"

#: the BLAS thread-count variables :func:`limit_blas_threads` sets
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")


def limit_blas_threads() -> None:
    """Run BLAS on one thread: the default of gnssrx's own entry points (``gnssrx``, the batch workers, the
    figure scripts and the test suite call this before numpy loads; a value already in the environment wins).

    Why: the receiver parallelises on its own threads (receiver/threads.py), so BLAS threads only
    oversubscribe the cores; and a threaded BLAS product (e.g. the fine-Doppler line powers' matrix products)
    sums in an order that depends on the thread count, which moves the last bit of an acquisition Doppler
    and, through a vector loop, whole results between thread counts.  A program that uses gnssrx as a
    library and wants results bit-identical to the command line's calls this before it imports numpy.
    Importing the package changes nothing.
    """
    for v in BLAS_THREAD_VARIABLES:
        _os.environ.setdefault(v, "1")
