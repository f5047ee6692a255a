"""Kinematic regions: what the k main markers predict (Lucero & Munhall 2008, Secs. III-V).

- :mod:`~facemotion.regions.prediction`: X = R11^-1 R12, the prediction of every marker from
  the k main markers, and the held-out error against k (Figs. 9-10);
- :mod:`~facemotion.regions.trajectory`: one marker's trajectory in a held-out sentence, measured
  and predicted (Fig. 9);
- :mod:`~facemotion.regions.redundancy`: markers that copy others, over a recording or a gap;
- :mod:`~facemotion.regions.optimality`: the QR subset against the exhaustive and greedy ones;
- :mod:`~facemotion.regions.selector`: a marker set with forced-in and excluded markers.
"""
