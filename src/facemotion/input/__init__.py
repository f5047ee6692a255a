"""Getting a lab's own recordings in: vendor exports, subject prefixes, non-marker points and
the segmentation of long takes into sentences.

- :mod:`~facemotion.input.segments`: the sheet's ``segments`` column (TextGrid tier, C3D event
  pairs or an interval table) and the cutting of a take into sentences.
- :mod:`~facemotion.input.c3d_points`: which C3D points are markers (Vicon's angles, forces,
  moments, powers, scalars ... are not).
- :mod:`~facemotion.input.prefixes`: "Subject:Marker" labels and the choice of one subject.
- :mod:`~facemotion.input.qualisys`, :mod:`~facemotion.input.optitrack`,
  :mod:`~facemotion.input.openface`: readers of Qualisys Track Manager TSV, OptiTrack Motive
  CSV and OpenFace 2.x landmark CSV exports.
"""
