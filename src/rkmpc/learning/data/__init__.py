"""On-track data: transition data sets, local-frame windows, control residuals, random excitation."""
