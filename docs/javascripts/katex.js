// Renders the formulas of the documentation with KaTeX (0.19.1, MIT licence, the npm
// package's dist/ files in javascripts/katex/ with only the woff2 fonts kept), so the
// site needs no network. pymdownx.arithmatex (generic mode) leaves inline formulas as
// \( ... \) and display formulas as \[ ... \] in elements of class "arithmatex".
document$.subscribe(({ body }) => {
  renderMathInElement(body, {
    delimiters: [
      { left: "\\(", right: "\\)", display: false },
      { left: "\\[", right: "\\]", display: true },
    ],
    ignoredClasses: ["md-search"],
    throwOnError: false,
  });
});
