"""Many chains: ensembles as arrays, their packing and the batched CPU engine."""
