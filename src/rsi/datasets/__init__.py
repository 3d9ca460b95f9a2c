"""Real reference/inspection pair datasets (DeepPCB) and the synthetic flaw-pattern generator."""
