"""The engineering sign-off report: HTML made self-contained, and its PDF (:mod:`.render`)."""
