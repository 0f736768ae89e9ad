"""Analytic formulas of the thesis (one function per equation) and the checks against ensembles."""
