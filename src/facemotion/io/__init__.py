"""Files in and out: one module per format, and the registry that lists them.

- :mod:`~facemotion.io.registry`: ``FORMATS``, the one list of formats the study reads, and
  :func:`~facemotion.io.registry.read_recording` (``facemotion.read``).
- :mod:`~facemotion.io.recording`: :class:`~facemotion.io.recording.Recording`, one take in mm.
- Formats: :mod:`~facemotion.io.c3d` (ezc3d) with :mod:`~facemotion.io.c3d_points` (which C3D
  points are markers), :mod:`~facemotion.io.trc`, :mod:`~facemotion.io.wide_csv`,
  :mod:`~facemotion.io.qualisys`, :mod:`~facemotion.io.optitrack`,
  :mod:`~facemotion.io.openface`, and :mod:`~facemotion.io.obj` (Wavefront meshes).
- :mod:`~facemotion.io.prefixes`: "Subject:Marker" labels and the choice of one subject.
- What they share: :mod:`~facemotion.io.base` (readable files, units, the fast text parser),
  :mod:`~facemotion.io.atomic` (whole files or none) and :mod:`~facemotion.io.npz`.

This layer knows files, not the analysis: it imports nothing of facemotion but
:mod:`facemotion.errors`.
"""
