/*
 * The built-in shader "null" for surface requests (Surface "null"): it does
 * nothing. relight uses this file when no null.sl is along the shader path; the
 * shader is named after the file, as every shader of the library is.
 */
surface null_surface()
{
}
