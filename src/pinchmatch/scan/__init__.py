"""Props from phone scans: read, rebuilt, closed, checked against a measurement, written as a
prop (``pinchmatch prop import``)."""
