"""The peers the exported C code is measured against: a CasADi Newton-Euler graph and Pinocchio's C++.

``rnea_sx`` (Newton-Euler on CasADi SX, exported through the same C path as ours) and ``speed``
(builds one C++ program with every implementation and times them on the same states).
"""
