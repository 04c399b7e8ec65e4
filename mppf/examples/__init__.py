"""Example data shipped with mppf: the example press, hull patches, and analytic full-size plates."""
