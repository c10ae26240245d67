"""Units a person reads and types: the CGS the scheme computes in, and the clinic's mmHg and mL/s.

Case files and the scheme are in CGS (cm, g, s; pressures in dyn/cm²).
"""

from __future__ import annotations

#: dyn/cm² in one mmHg (the conventional millimetre of mercury, 133.322387415 Pa)
MMHG = 1333.22387415
