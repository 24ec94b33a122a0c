"""A deployment's backups: the database in a consistent snapshot and every file the rows name
(clips, reports, checkpoints, sampled motion), with a manifest of each file's size and
SHA-256; and the restore that brings them back into an empty database and folders.

``backup.json`` says what a backup holds (``manifest``); ``database`` dumps and loads each
engine's snapshot; ``files`` lists, copies and checks the folders; ``backup`` and ``restore``
put them together for the two management commands.
"""
