"""The files a measured cell comes in: the native experiment file (`h5.py`), the
single-cell CSV (`csvcell.py`), and the instruments' files (`instruments.py`: which
reader for which file, the height and volume policy) read by `jpk/` and `bruker/`
into `recording.Recording`s; `textfiles.py` opens text exports plain or gzipped."""
