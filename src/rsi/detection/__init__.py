"""Seed §2.4: flaw models, noise model, likelihood-ratio flaw detection and ROC analysis."""
