"""The ground floor: what every other part of rkmpc shares.

Observations and commands with their field names, one angle-wrapping
convention, atomic file writes, JSON conversion, package versions, the
exceptions rkmpc raises on purpose and the checks of validated settings.
Nothing here imports another part of rkmpc.
"""
