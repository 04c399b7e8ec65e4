"""Measurement: a scan of the formed plate compared with its design, deviations, statistics, punch deviations."""
