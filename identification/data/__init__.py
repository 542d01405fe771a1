"""Recordings and what is done to them before any fit: reading, writing, checking, filtering, differentiation.

``recording`` (the :class:`Recording` value), ``table`` (the checked named columns a file holds),
``csvfile``, ``npzfile``, ``matfile`` (MATLAB) and ``rosbag`` (ROS 2 bags) (the readers), ``io``
(recordings from and to files), ``preprocessing`` (zero-phase filtering, central differences,
resampling), ``excitation_check`` (refuses recordings in which a joint did not move enough to
identify anything), ``payload`` (a known calibration mass, as the user describes it in
``payload.json``), ``torque_constants`` (the drives' constants a recording of currents is read with),
``dataset`` (the folder of the paper's four calibration experiments).
"""
