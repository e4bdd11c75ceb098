#!/bin/sh
# Makes docs/images/demo.png (the README's picture): a demo scan's contact sheet beside its model
# rendered by three.js in headless Chromium. Needs a build (build/station/apps/revolve),
# chromium, libjs-three and ImageMagick (apt-get install imagemagick). Run from the checkout:
#   sh docs/images/make_demo_image.sh
set -eu
scan=$(mktemp -d)/demo
build/station/apps/revolve scan --out "$scan" >/dev/null
render=$(mktemp -d)
chromium --headless --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader \
  --allow-file-access-from-files --virtual-time-budget=20000 --window-size=640,576 \
  --screenshot="$render/model.png" \
  "file://$(pwd)/docs/images/render_model.html?model=file://$scan/model/model.glb" 2>/dev/null
# ImageMagick's own convert (a stand-in may shadow it on PATH).
im=/usr/bin/convert
$im "$scan/contact_sheet.png" -resize x576 "$render/sheet.png"
$im "$render/sheet.png" "$render/model.png" -background white +append -resize 1100x \
  -colors 256 -strip docs/images/demo.png
ls -l docs/images/demo.png
