"""Imported by the local pool's forkserver (receiver/batch/executors.py): warms it once
(:func:`receiver.batch.warm.warm`), so that every pool worker is forked warm."""
from .warm import warm

warm()
