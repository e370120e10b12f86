"""Recording: the flight recorder's bag segments, their retention, repair and summaries (`plem bag`)."""
