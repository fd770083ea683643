"""The population of measured cells: statistics per frequency (`summary.py`) and their
figures (`figures.py`); the population answer (`answer.py`: population.json) from the
random-effects populations (`random_effects.py`), the frequency trend (`mean_trend.py`; the
design-weighted mixed model `trend.py` beside it) and
paired tests (`paired.py`), with its report section (`report.py`) and figures
(`answer_figures.py`)."""
