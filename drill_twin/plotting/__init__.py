"""Figures (matplotlib, Agg): time histories and spectra like the paper's Figs. 7-16."""
