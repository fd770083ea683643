"""JPK force curves: text exports (`text.py`) and binary archives (`archive.py`,
with `properties.py` their headers and `channels.py` their encoded channels)."""
