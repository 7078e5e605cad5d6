/* Private: colour differences (colour.c). */
#ifndef SEPBRDF_UTIL_COLOUR_H
#define SEPBRDF_UTIL_COLOUR_H

/* Linear sRGB (D65 white, Y of white 1) to CIELAB against D65. */
void sb_srgb_to_lab(const double rgb[3], double lab[3]);
/* CIEDE2000 colour difference (kL = kC = kH = 1) of two CIELAB colours;
 * about 1 is just noticeable, above 2 visible side by side. */
double sb_ciede2000(const double lab1[3], const double lab2[3]);
/* CIEDE2000 of two linear sRGB colours after multiplying both by exposure,
 * negative channels clipped to 0 (what a display shows). */
double sb_delta_e_exposed(const double ref[3], const double rec[3], double exposure);

#endif
