"""The ground every other package stands on: pure formulas on arrays (numpy, numba), with their parameters.

Geometry of the base (base), social forces (forces, paper eqs. 8-10), conversation groups (humans, layouts), reward
terms (reward, eqs. 11-15), the Vector observation layout (observation), the safety shield (shield), the task's
rules (task) and camera projection (camera). Imports nothing of the package but ``params``, ``errors``, ``urdf``.
"""

from .compile_cache import use_source_keyed_cache

use_source_keyed_cache()
