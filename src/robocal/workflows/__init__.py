"""Jobs that orchestrate sources → core → formats (one module per job)."""
