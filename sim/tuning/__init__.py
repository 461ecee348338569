"""Controller tuning studies: trim over an envelope, linearisation, loop analysis, gain tuning.

Modules (one concept each):

- :mod:`sim.tuning.evaluator`   JSBSim as a function: state + inputs -> state derivatives (SI)
- :mod:`sim.tuning.surrogate`   casadi model of the HAPS longitudinal trim equations, read from the
  aircraft's XML tables (independent of JSBSim's solver)
- :mod:`sim.tuning.trim_haps`   HAPS trim over altitude x TAS: JSBSim's trim and the casadi trim
- :mod:`sim.tuning.trim_quad`   multirotor trim (hover, forward flight) by root-finding on JSBSim
- :mod:`sim.tuning.report`      trim tables (CSV, Markdown) and plots
- :mod:`sim.tuning.linearize`   central-difference A, B from JSBSim; :mod:`sim.tuning.modes`
- :mod:`sim.tuning.loops`       margins and step figures of a loop (shared analysis)
- :mod:`sim.tuning.loops_haps`  HAPS roll and pitch holds as transfer functions
- :mod:`sim.tuning.loops_tecs`  HAPS TECS loops (thrust lag measured in JSBSim)
- :mod:`sim.tuning.loops_quad`  quadrotor rate, attitude, velocity and position loops
- :mod:`sim.tuning.catalog`     every loop of both airframes: gains, transfer functions, step
- :mod:`sim.tuning.steps`       closed-loop JSBSim step of each loop
- :mod:`sim.tuning.tuner`       gains for a requested crossover / phase margin, verified in JSBSim
- :mod:`sim.tuning.cli`         ``tune_main(argv)``: ``trim``, ``linearize``, ``margins``, ``gain``

Units SI and radians throughout; JSBSim's feet and slugs stay in :mod:`sim.tuning.evaluator`.
"""
