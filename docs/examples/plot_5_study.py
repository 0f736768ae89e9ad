r"""
A thesis study: the slope of the high band against 2H + 3
=========================================================

:mod:`mdroll.studies` reproduces the thesis's parameter studies (:doc:`/studies`): each runs its
ensembles through :func:`mdroll.run_specs`, measures what the thesis claimed with standard
errors, and gives a verdict per claim. Here the study of the thesis's Figure 4: the exponent
:math:`\alpha` of the power-law band, :math:`C \propto q^{-\alpha}`, against eq 23,
:math:`\alpha = 2H + 3`, at the ``test`` size (seconds on a CPU); ``mdroll study slope --full``
runs it at the thesis's scale on a GPU.
"""

import matplotlib.pyplot as plt

from mdroll.studies import run_study
from mdroll.studies.report import format_table

run = run_study("slope", size="test", device="cpu", seed=0)
print(format_table(run.record))

# %%
# The study's own figures: the spectra it measured and alpha(H) against eq 23.

for figure in run.figures:
    fig = plt.figure(figsize=figure.size, dpi=100)
    figure.draw(fig)
    fig.suptitle(figure.caption, fontsize=8, wrap=True)
plt.show()
