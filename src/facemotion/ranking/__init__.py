"""Marker ranking by QR with column pivoting (Lucero & Munhall 2008, Sec. III).

The displacement matrix A (3F x n, frame-major rows, one column per marker, mm) is factored as

    A P = Q R                                     (QR with column pivoting, Golub & Van Loan 5.4)

The first pivot is the marker with the largest motion; each later pivot is the marker whose
motion is least explained by the markers already chosen: |r_kk| is the norm of its component
orthogonal to the span of the previous pivots (a 2-norm of mm values, so in mm).

Normalisation of R ("R values normalized to the size of R", Fig. 2).  ``R_NORMALISATIONS``:

``"none"`` (default)
    |r_kk| itself, the 2-norm (mm) of the pivot's orthogonal component, and ||R22||_2 compared
    with epsilon as printed in Sec. III.  This is the only reading under which the paper's
    r56 = 22.70 mm is a possible size for the 56th pivot (see docs/methods.md).
``"per_coordinate"``
    |r_kk| / sqrt(3M): the RMS of that component per coordinate sample (``r_rms``).
``"per_frame"``
    |r_kk| / sqrt(M): its RMS 3-D size per frame.

Epsilon-rank (Sec. III, eq. 1): partition R after k pivots, R22 = R[k:, k:]; the paper's
epsilon-rank is the smallest k with ||R22||_2 <= epsilon (``epsilon_rank``), which bounds the
singular values sigma_{k+1}(A) <= ||R22||_2 (Chan 1987).  Since R[k+1:, k+1:] is a submatrix of
R[k:, k:], ||R22||_2 is non-increasing in k and a bisection needs only O(log n) 2-norms.  The
older count of diagonal entries above epsilon is kept beside it (``diagonal_count``); it is never
larger than the epsilon-rank, because |r_jj| <= ||R[k:, k:]||_2 for every k <= j.

Three routes give the same pivots and the same |R| (up to the sign of each row of R, which we fix
so that diag(R) >= 0):

``"scipy"``
    ``scipy.linalg.qr(A, pivoting=True)`` on the full matrix (LAPACK dgeqp3).  The reference.
``"tsqr"``
    One streaming pass of unpivoted QR over row blocks, ``R0 = qr([R0; A_block])`` (TSQR), giving
    an n x n R0 with A = Q0 R0.  Column norms and all inner products of A are those of R0
    (A^T A = R0^T R0), so pivoted QR of R0 makes exactly the choices pivoted QR of A would make.
``"gram"``
    One pass G = A^T A (BLAS syrk), then diagonal-pivoting Cholesky of G: at step k the Schur
    complement diagonal is the squared norm of each column's residual orthogonal to the pivots
    so far, so choosing its largest entry is the QR pivot rule, and the Cholesky factor is R.
    Accuracy: forming G squares the condition number.  The Schur complement diagonal r_kk^2 is
    computed with an absolute error of about eps * r_11^2, so the relative error of r_kk is about
    eps * (r_11 / r_kk)^2 / 2.  Once r_kk / r_11 approaches sqrt(eps) ~ 1e-8 the Gram route
    returns noise (and may pick different pivots among the near-dependent columns).
``"auto"``
    The Gram route, falling back to TSQR when some r_kk / r_11 < ``GRAM_RATIO_LIMIT`` (1e-4,
    i.e. a relative error in r_kk above ~1e-8), e.g. when a marker is a copy of another; with
    ``k_max`` set and at least ``RANDOMIZED_MIN_N`` markers, the randomized route.
``"randomized"``
    The first ``k_max`` pivots from a Gaussian sketch of A, refined on A itself (see
    :mod:`facemotion.ranking.randomized`); two passes over A of O(rows n k_max) flops
    instead of the Gram's O(rows n^2).

A may be an array or a :class:`facemotion.ingest.displacement_file.RowBlocks` (A on disk): the
"gram", "tsqr" and "randomized" routes read it in blocks of rows, holding one block at a time;
"scipy" reads it whole. The Gram pass runs on ``threads`` cores (:mod:`facemotion.ranking.gram`).

Fewer rows than markers (e.g. 150 frames of 457 landmarks): A has rank at most rows, so only
the first ``rows`` pivots are chosen by the QR rule; the others are exact combinations of them
and follow in their original order with r = 0. ``MarkerRanking.n_ranked`` says how many pivots
were ranked (also fewer when ``k_max`` limits the ranking), and a warning is logged.

Bad input raises :class:`facemotion.errors.InputError`: NaN or inf in A, and a static marker (a
column whose largest absolute value is below 1e-12 mm: it has no motion to rank, and its r_kk
would be exactly zero).

Modules: :mod:`~facemotion.ranking.result` (the ranking and the checks every route shares),
:mod:`~facemotion.ranking.gram` (the Gram pass), :mod:`~facemotion.ranking.qr` (TSQR and
pivoted Cholesky), :mod:`~facemotion.ranking.randomized`, :mod:`~facemotion.ranking.routes`
(the entry point), :mod:`~facemotion.ranking.epsilon_rank` and
:mod:`~facemotion.ranking.stability` (R against the number of sentences, Fig. 3).
"""
