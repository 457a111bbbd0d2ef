"""Exports for other tools: :mod:`~thirdhand.export.rrd` writes Rerun recordings."""
