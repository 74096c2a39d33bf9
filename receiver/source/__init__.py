"""Sample sources: recorded IF files (``io``: memory-mapped chunked reader, formats, quantisation)."""
