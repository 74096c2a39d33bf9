"""The run file (HDF5): record dtypes (``record``) and the writer (``writer``)."""
