"""Friction: models, their numeric and CasADi forms, start values and fits (paper section 3.3).

``models`` (LuGre, Coulomb-viscous and Stribeck parameters, the check of friction-experiment
arrays), ``lugre_step`` (the exact LuGre step over a sample interval: the exponential integrator
and its sub-step layout), ``simulation`` (numeric LuGre simulation along a sampled velocity),
``expressions`` (the LuGre model as CasADi expressions and Functions), ``start`` (start values from
the high-speed part of a recording), ``shooting_nlp`` (the multiple-shooting NLP assembled from
per-interval CasADi Functions), ``shooting`` (the multiple-shooting LuGre fit with Ipopt),
``measurement`` (the model of what a friction experiment measures: held currents and central
differences of the encoder), ``baseline`` (the paper's Nelder-Mead fit, as a peer for benchmarks).
"""
