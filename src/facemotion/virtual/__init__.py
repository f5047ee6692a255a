"""The built-in virtual subjects: talkers whose motion is known, written as real files.

- :mod:`~facemotion.virtual.designs`: the designs (S1, S2a, S2b, S; the dense D468 and
  D5023), listed once;
- :mod:`~facemotion.virtual.talker`: the 57-marker talker of Lucero & Munhall's designs, and
  the published facts it is calibrated on (``CALIBRATION``);
- :mod:`~facemotion.virtual.dense`: the same talker's motion at the vertices of a face mesh.
"""
