"""Files sewmech writes and reads: :mod:`.outdir` (output directories that never lose a user's
file: staged, locked, committed at once) and :mod:`.io` (CSV and JSON writers and readers,
every file written atomically)."""
