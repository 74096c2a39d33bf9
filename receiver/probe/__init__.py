"""What is in an IF file: byte statistics (``stats``), the short acquisition over candidate formats, rates
and IFs (``search``), ``gnssrx probe`` (``cli``) and the hints a run that finds nothing prints (``hints``)."""
