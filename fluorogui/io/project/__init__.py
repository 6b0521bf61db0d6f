"""Project files: the .fluoro document, its migrations and the lock that keeps one writer at a time."""
