"""The database seams: participant pages' queries compiled once, PostgreSQL's pipelined round
trips, the embedded SQLite backend, and every private part of Django they drive (django_internals)."""
