"""Writers: atomic output folders, JSON, VTU fields and figures (nothing here imports
plug-ins or commands)."""
