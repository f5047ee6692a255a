"""Every figure of the study, one module per figure, and the style they share.

Figures are built on :class:`matplotlib.figure.Figure` without pyplot and saved as bytes
without time- or machine-dependent metadata (:mod:`~facemotion.plots.save`), so a rerun
gives the same files. :mod:`~facemotion.plots.animation` draws Fig. 8's animation.
"""
