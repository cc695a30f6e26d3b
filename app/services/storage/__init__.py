"""How a run's arrays are kept: compressed column blocks, profile blocks, and retention."""
