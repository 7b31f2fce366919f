"""Record conditioning and features: timeline repair, peaks, crossings, envelopes."""
