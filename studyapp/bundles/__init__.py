"""A study's bundle: the whole study with its data as one zip (its rows, participants and ratings,
definition, checkpoints, motion and videos), which ``export_study`` writes and ``import_study`` reads.
The recipe alone, to make a new study like it, is a definition (``studyapp.definitions``).

    manifest.py     the manifest: every file's SHA-256 and size, the format version, the code version
    pseudonyms.py   platform ids replaced by a keyed hash (HMAC-SHA-256)
    records.py      the study's rows as JSON records, and the layout of the bundle's files
    writing.py      a study into a bundle (a zip written atomically)
    reading.py      a bundle read into a scratch folder, every file checked against the manifest
                    (hostile bundles refused there)
    importing.py    a read bundle re-created as a new, closed study: rows in one transaction, files
                    moved into place only when it commits
"""
