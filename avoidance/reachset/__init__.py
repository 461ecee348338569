"""Reach-set avoidance (spec ../shared/design/avoidance-reach-set.md; seeds 000/004).

Modules, one concept each: ``config`` (parameters), ``frames`` (NED <-> z-up GCF <-> LCF, polar),
``movement`` (Movement Automaton, segments), ``reference`` (reference trajectory), ``grid``
(Avoidance Grid geometry), ``tree`` / ``expansion`` / ``cache`` / ``metrics`` (reach sets),
``threats.*`` (per-source ratings), ``situation`` (threat collection), ``fusion`` (data fusion,
reachability), ``gridrun`` (avoidance grid run), ``mission`` (mission control run), ``record``
(decision records, Foxglove scene), ``planner`` (``ReachSetAvoider``, the planner protocol).
"""
