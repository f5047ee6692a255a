"""From recordings to the displacement matrix A: one path for every recording, virtual or real.

The stages, in the order :func:`~facemotion.ingest.loading.load_dataset` runs them:

1. :mod:`~facemotion.ingest.segments`: long takes cut into sentences (TextGrid tiers, C3D
   events, interval tables);
2. :mod:`~facemotion.ingest.validation`: units, length, rate, face shape and outliers of each
   take;
3. :mod:`~facemotion.ingest.head_motion`: rigid head motion removed;
4. :mod:`~facemotion.ingest.copy_fill` and :mod:`~facemotion.ingest.gaps`: missing samples
   filled (by copying a marker's displacement, by interpolation, by PCA) and reported;
5. :mod:`~facemotion.ingest.displacements`: A, each sentence minus its neutral pose, written
   by :mod:`~facemotion.ingest.displacement_file` in a form read back in blocks of rows.
"""
