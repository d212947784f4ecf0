"""Frame sources of simulated sequences: rendering on demand, the on-disk frame cache and its codec, world variants."""
