"""Report sections: each turns analysis and metrology results for one test into its part of results.json and the HTML."""
