"""Benchmarks against the field: ``smartcar-bench barn`` runs a policy or the DWA baseline on
the BARN test worlds and reports the challenge's table (``runner``, ``report``, ``cli``)."""
