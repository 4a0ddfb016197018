"""Worlds shipped with the package: the BARN benchmark's 300 cylinder fields (``barn``)."""
