"""Input: clouds as the caller gives them, checked and prepared.

* :mod:`~o3d_spectral.io.cloud`: Open3D, tensor and numpy clouds to checked float64
  arrays; down-sampling, normals checked, estimated when missing (``PreparedCloud``,
  ``CloudReading``);
* :mod:`~o3d_spectral.io.signs`: normals' signs between neighbours (disagreeing, or back
  to back on walls thinner than the points' spacing);
* :mod:`~o3d_spectral.io.normals`: orientation rules, a single view recognised from its
  normals and depth;
* :mod:`~o3d_spectral.io.files`: cloud files checked against their header before Open3D
  reads them.

Imports only its own modules and the package's private helpers (``tests/test_layers.py``).
"""
