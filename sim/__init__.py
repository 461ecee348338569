"""The co-simulation engine: plants, scheduler, scenarios, world, logging, runner and CLI."""

__version__ = "0.1.0"
