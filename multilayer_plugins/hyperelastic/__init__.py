"""Hyperelastic layers of the arterial wall, thick and thin, and the strain energies they share.

* :mod:`.band`: the thick bands ``neo-hookean`` and ``hgo`` (total Lagrangian, mean dilatation), on
  :mod:`.kinematics` (the deformation gradient of a band) and :mod:`.laws` (the isochoric and volumetric energies
  in the invariants of F);
* :mod:`.membrane`: the thin layers ``neo-hookean-membrane`` and ``hgo-membrane`` (an incompressible wall in plane
  stress), on :mod:`.membrane_laws` (the energies reduced to the stretches λθ, λz);
* both take the fibres' energy of Holzapfel, Gasser & Ogden (2000) from :func:`.membrane_laws.hgo_fibre`.
"""
