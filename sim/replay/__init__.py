"""Reading runs back: arrays per topic, metrics, reports, comparisons."""
