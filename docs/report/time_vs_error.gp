# time_vs_error.gp — written by report_cull; run from its own folder:
#   cd docs/report && gnuplot time_vs_error.gp
# draws time_vs_error.svg and time_vs_error.png (the same figure).
$city << EOD
# time_us rate_pct threads label
23.098 97.135 1 "spheres"
24.535 97.135 2 "spheres"
26.239 97.131 1 "+AABB"
23.954 97.131 2 "+AABB"
55.784 97.133 1 ">=1px"
42.750 97.133 2 ">=1px"
56.746 96.976 1 ">=2px"
44.092 96.976 2 ">=2px"
56.695 96.647 1 ">=4px"
42.745 96.647 2 ">=4px"
229.393 66.929 1 "occ 128x64"
181.198 66.929 2 "occ 128x64"
241.836 41.305 1 "occ 256x114"
179.285 41.305 2 "occ 256x114"
278.500 23.400 1 "occ 512x256"
236.185 23.400 2 "occ 512x256"
429.476 15.402 1 "occ 1280x720"
361.029 15.402 2 "occ 1280x720"
EOD
$city_labels << EOD
# label_x label_y text point_x point_y moved
25.0370 102.188 "spheres" 23.098 97.135 1
28.4417 92.078 "+AABB" 26.239 97.131 1
60.4669 98.817 ">=1px" 55.784 97.133 0
61.5096 102.029 ">=2px" 56.746 96.976 1
61.4543 94.963 ">=4px" 56.695 96.647 0
248.6497 68.613 "occ 128x64" 229.393 66.929 0
262.1373 42.989 "occ 256x114" 241.836 41.305 0
301.8785 25.084 "occ 512x256" 278.500 23.400 0
465.5295 17.086 "occ 1280x720" 429.476 15.402 0
EOD
$city_front << EOD
23.098 97.135
23.954 97.131
42.745 96.647
179.285 41.305
236.185 23.400
361.029 15.402
15031.7 15.402
EOD
$rnd << EOD
# time_us rate_pct threads label
11.553 87.389 1 "spheres"
17.369 87.389 2 "spheres"
9.955 87.350 1 "+AABB"
16.936 87.350 2 "+AABB"
30.585 87.109 1 ">=1px"
29.205 87.109 2 ">=1px"
31.073 86.764 1 ">=2px"
29.235 86.764 2 ">=2px"
33.584 86.311 1 ">=4px"
28.596 86.311 2 ">=4px"
221.810 32.496 1 "occ 128x64"
174.843 32.496 2 "occ 128x64"
222.444 20.092 1 "occ 256x114"
165.963 20.092 2 "occ 256x114"
263.901 11.999 1 "occ 512x256"
197.993 11.999 2 "occ 512x256"
414.689 7.361 1 "occ 1280x720"
388.971 7.361 2 "occ 1280x720"
EOD
$rnd_labels << EOD
# label_x label_y text point_x point_y moved
12.5234 82.336 "spheres" 11.553 87.389 1
10.7910 92.403 "+AABB" 9.955 87.350 1
33.1530 92.162 ">=1px" 30.585 87.109 1
33.6813 81.711 ">=2px" 31.073 86.764 1
36.4038 87.995 ">=4px" 33.584 86.311 0
240.4307 34.180 "occ 128x64" 221.810 32.496 0
241.1170 21.777 "occ 256x114" 222.444 20.092 0
286.0542 13.684 "occ 512x256" 263.901 11.999 0
449.5003 9.046 "occ 1280x720" 414.689 7.361 0
EOD
$rnd_front << EOD
9.955 87.350
28.596 86.311
165.963 20.092
197.993 11.999
388.971 7.361
15031.7 7.361
EOD
set encoding utf8
set logscale x
set xrange [6.96873:1503.17]
set yrange [0:105]
set grid xtics mxtics ytics lc rgb '#dddddd'
set xlabel 'time per query, µs (median; log scale)'
set ylabel 'false-visible rate, % of reported entities'
set key top right box opaque
do for [term = 1:2] {
  if (term == 1) { set terminal svg size 1500,650 dynamic font 'DejaVu Sans,12' background '#ffffff'; set output 'time_vs_error.svg'; psz = 1.0 }
  if (term == 2) { set terminal pngcairo size 1500,650 font 'DejaVu Sans,10' background '#ffffff'; set output 'time_vs_error.png'; psz = 1.3 }
  set multiplot layout 1,2 title "Culling: time per query against false-visible rate (truth: exact frustum + 1920x1080 ray caster)\n{/*0.8 machine: 2 cpus, AMD EPYC; 2026-11-21}"
  set title 'city scene walk'
  plot $city_front using 1:2 with steps lw 2 lc rgb '#2ca02c' title 'Pareto front', \
       $city_labels using 1:2:($4 - $1):($6 > 0 ? $5 - $2 : 1/0) with vectors nohead lc rgb '#aaaaaa' notitle, \
       $city using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps psz lc rgb '#1f77b4' title '1 thread', \
       $city using 1:($3 == 2 ? $2 : 1/0) with points pt 9 ps psz * 1.15 lc rgb '#d62728' title '2 threads', \
       $city_labels using 1:2:3 with labels left font ',10' notitle
  set title 'random towns (3)'
  plot $rnd_front using 1:2 with steps lw 2 lc rgb '#2ca02c' title 'Pareto front', \
       $rnd_labels using 1:2:($4 - $1):($6 > 0 ? $5 - $2 : 1/0) with vectors nohead lc rgb '#aaaaaa' notitle, \
       $rnd using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps psz lc rgb '#1f77b4' title '1 thread', \
       $rnd using 1:($3 == 2 ? $2 : 1/0) with points pt 9 ps psz * 1.15 lc rgb '#d62728' title '2 threads', \
       $rnd_labels using 1:2:3 with labels left font ',10' notitle
  unset multiplot
  set output
}
