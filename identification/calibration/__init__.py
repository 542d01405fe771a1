"""The paper's calibration: four identification steps, a joint refinement, a consistency check.

``estimator`` (the estimator bases: what every step shares, and the least squares of the linear
steps), ``inputs`` (checks shared by the steps), ``excitation`` (what each step's data must excite,
refused before any fit), ``out_and_back`` (folding out-and-back experiments, the motor step's sweeps),
``steps`` (torque constants, gravity, inertial),
``friction_step`` (the LuGre step on the friction experiments), ``payload`` (the torques of a
known load), ``preparation`` (the experiments filtered, folded, decimated and split per step),
``refinement`` (all parameters together with Ipopt), ``consistency`` (positive-definite mass
matrix), ``extra_terms`` (known additive torques, a diagnosis finding, fitted inside the steps),
``extra_passes`` (the passes that settle them between the steps), ``pipeline`` (the steps in order),
``report`` (the validation table, the paper's Table 3)
and ``result`` (:class:`IdentifiedModel` and its files).
"""
