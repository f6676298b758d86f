"""DCC building blocks: XML helpers, D-SI units, the vocabulary, results and budgets as XML."""
