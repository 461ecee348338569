"""Evaluation testbeds from the specs, outside the planner packages (a planner must not be able
to import the world's truth): the MPTP thesis scenarios (``mptp_thesis``), their HAPS-scaled
closed-loop versions (``mptp_haps``), the open-loop MPTP flyer (``mptp_openloop``), the geometric
avoider's encounters (``geometric_encounters``) and its cost-cap sweep (``geometric_sweep``)."""
