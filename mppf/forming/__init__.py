"""Forming: material, springback, the planner's plate model and springback pre-compensation."""
