"""Robot models as data: parameter tables with units and citations."""
