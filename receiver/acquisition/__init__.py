"""Acquisition stage: finding the satellites in the samples and measuring their code phase and Doppler.

Modules, one concern each:

* :mod:`.code_search` -- the FFT parallel code-phase search over a Doppler grid, its detection statistic, the
  verification dwell, fine Doppler refinement and cross-correlation rejection;
* :mod:`.high_sensitivity` -- the high-sensitivity second pass (10-ms blocks, half-bit sums) for signals
  the normal search misses;
* :mod:`.reacquisition` -- the narrow search around a predicted code phase and Doppler that re-opens a
  channel after a loss of signal.

The names below are the stage's public interface; private helpers are imported from their module.
"""
from .code_search import (AcqResult, cross_correlation_image, refine_doppler, refine_doppler_squared,
                          reject_cross_correlations, search, verify, verify_columns)

__all__ = ["AcqResult", "cross_correlation_image", "refine_doppler", "refine_doppler_squared",
           "reject_cross_correlations", "search", "verify", "verify_columns"]
