"""Recordings and what is done to them before any fit: reading, writing, filtering, differentiation.

``recording`` (the :class:`Recording` value), ``io`` (CSV and NPZ readers and writers),
``preprocessing`` (zero-phase filtering, central differences, resampling), ``payload`` (a known
calibration mass, as the user describes it in ``payload.json``), ``dataset`` (the folder of the
paper's four calibration experiments).
"""
