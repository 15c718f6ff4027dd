"""Figures: :mod:`.figures` draws and saves them (PNG, SVG and their data as CSV; worker
processes for a report), :mod:`.fastdraw` answers matplotlib's repeated questions from caches
while a figure is drawn, :mod:`.plot` draws kinematics results for library users."""
