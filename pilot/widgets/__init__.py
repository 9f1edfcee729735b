"""The Pilot Interface widgets (Qt): one module per widget."""
