"""Functions a case gives: formulas in (t, z, r), their domains, and the pressure histories of loads."""
