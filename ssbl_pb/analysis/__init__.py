"""Analysis and reporting on top of the env and training: evaluation of a policy over seeded episodes
(``evaluation``), learned vs baseline (``compare``, ``compare_plot``), summaries, CIs and path plots
(``report``), the perceptual study (``study``), videos (``video``), simulator speed (``bench``) and the paper's
Table I (``table1``, ``table1_report``)."""
