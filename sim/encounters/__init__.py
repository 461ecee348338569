"""Encounter campaigns: sampled pairwise encounters flown mitigated and unmitigated, judged by
NMAC, loss of well clear and mission completion (``cosim encounters``)."""
