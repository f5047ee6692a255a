"""facemotion: how the human face moves during speech.

Two classic analyses, reproducible end to end:

* independent kinematic regions by QR with column pivoting (Lucero & Munhall 2008);
* a finite-element lip model trained from data (Basu & Pentland 1997).
"""

__version__ = "0.1.0"
