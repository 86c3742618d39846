function text = spm_pairs(pairs)
%SPM_PAIRS  Link pairs of an answer (a list of [link, link]) as 'a-b, c-d' text;
%   'none' when there is no pair.
  if isempty(pairs)
    text = 'none';
    return
  end
  names = cell(1, numel(pairs));
  for k = 1:numel(pairs)
    names{k} = [pairs{k}{1} '-' pairs{k}{2}];
  end
  text = strjoin(names, ', ');
end
