"""Tasks: each one class written once over the cars' state (``base.Task``), registered by name
with the ids made from it (``registry``)."""
