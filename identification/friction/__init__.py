"""Friction: models, start values and fits.

``models`` (LuGre, Coulomb-viscous and Stribeck, numeric and as CasADi expressions, and the exact
LuGre step over a sample interval), ``start`` (start values from the high-speed part of a
recording), ``shooting`` (the multiple-shooting LuGre fit with Ipopt), ``measurement`` (the model of
what a friction experiment measures: held currents and central differences of the encoder),
``baseline`` (the paper's Nelder-Mead fit, as a peer for benchmarks).
"""
