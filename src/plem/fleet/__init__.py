"""A fleet's recordings as one dataset: bags exported to Parquet, and the queries and reports over it."""
