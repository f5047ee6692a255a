"""The papers' published values and their statements beside the study's own.

- :mod:`~facemotion.papers.lucero_munhall` and :mod:`~facemotion.papers.basu_pentland`: each
  paper's values (with their places: Table I, Fig. 9, eq. 5, ...) and the rows that compare
  them with ours;
- :mod:`~facemotion.papers.table`: the table's columns, verdicts and rules;
- :mod:`~facemotion.papers.comparison`: the table from a study's outputs, and as markdown.

This layer reads the study's output tables; it does not compute them.
"""
