"""Certificate building blocks: the document model, its parts, rounding, plots, method texts."""
