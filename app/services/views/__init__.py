"""What is read off the stored data for people: chart views, CSV/GeoJSON exports, the HTML
report and its sections, chainage notation, windows and decimated signals."""
