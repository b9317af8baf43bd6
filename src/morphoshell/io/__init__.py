"""Files in and out: problem files, traced midlines, and JSON/CSV output.

Problem files (TOML) and their overrides, the packaged examples and the writers
of results (:mod:`.problem_files`); traced midlines from Fiji/ImageJ and CSV
(:mod:`.traces`).  Every reader names the file and the offending entry.
"""
